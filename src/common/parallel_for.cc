#include "autocal/common/parallel_for.h"

#include <algorithm>
#include <exception>
#include <system_error>
#include <thread>
#include <vector>

namespace autocal {

int ParallelChunks(int64_t count, int num_threads) {
  if (count <= 1 || num_threads <= 1) return 1;
  // More threads than cores only add switching; hardware_concurrency() is 0 when unknown.
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  return static_cast<int>(std::min<int64_t>(count, std::min(num_threads, cores)));
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
  int first_inline = chunks;  // chunks from here on run on the calling thread
  for (int chunk = 1; chunk < chunks; ++chunk) {
    try {
      workers.emplace_back(run, chunk);
    } catch (const std::system_error&) {
      // No thread to be had (resource limits): the rest runs here, nothing is lost.
      first_inline = chunk;
      break;
    }
  }
  run(0);
  for (int chunk = first_inline; chunk < chunks; ++chunk) run(chunk);
  for (std::thread& worker : workers) worker.join();
  for (const std::exception_ptr& error : errors) {
    if (error) std::rethrow_exception(error);
  }
}

}  // namespace autocal
