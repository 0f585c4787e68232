#include "autocal/common/parallel_for.h"

#include <algorithm>
#include <exception>
#include <thread>
#include <vector>

namespace autocal {

int ParallelChunks(int64_t count, int num_threads) {
  if (count <= 1 || num_threads <= 1) return 1;
  return static_cast<int>(std::min<int64_t>(count, num_threads));
}

void ParallelFor(int64_t begin, int64_t end, int num_threads,
                 const std::function<void(int64_t, int64_t, int)>& body) {
  const int64_t count = end - begin;
  if (count <= 0) return;
  const int chunks = ParallelChunks(count, num_threads);
  if (chunks == 1) {
    body(begin, end, 0);
    return;
  }
  const auto chunk_begin = [&](int chunk) { return begin + count * chunk / chunks; };
  std::vector<std::exception_ptr> errors(static_cast<size_t>(chunks));
  const auto run = [&](int chunk) {
    try {
      body(chunk_begin(chunk), chunk_begin(chunk + 1), chunk);
    } catch (...) {
      errors[static_cast<size_t>(chunk)] = std::current_exception();
    }
  };
  std::vector<std::thread> workers;
  workers.reserve(static_cast<size_t>(chunks - 1));
  for (int chunk = 1; chunk < chunks; ++chunk) workers.emplace_back(run, chunk);
  run(0);
  for (std::thread& worker : workers) worker.join();
  for (const std::exception_ptr& error : errors) {
    if (error) std::rethrow_exception(error);
  }
}

}  // namespace autocal
