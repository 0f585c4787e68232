#include "autocal/common/parallel_for.h"

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <system_error>
#include <thread>
#include <vector>

namespace autocal {
namespace {

// One ParallelFor call: its chunks are claimed one at a time, by the caller and by the
// pool's workers, under the pool's mutex.
struct Job {
  const std::function<void(int)>* run_chunk = nullptr;
  int chunks = 0;
  int next = 0;  // the next chunk to claim
  int done = 0;  // chunks finished
};

// The process's worker threads, started on first use: one per core beyond the caller's.
// Workers sleep until a job is offered; a job whose chunks all got claimed leaves the queue,
// and its caller waits until the last claimed chunk has finished. A caller never waits for
// a chunk nobody claimed: it runs every chunk the workers have not taken, so a ParallelFor
// inside a chunk (or with every worker busy) still completes.
class WorkerPool {
 public:
  static WorkerPool& Instance() {
    static WorkerPool* pool = new WorkerPool();  // never destroyed: workers outlive main()
    return *pool;
  }

  // Runs chunk 0 on the calling thread and the others wherever they get claimed.
  void Run(Job* job) {
    std::unique_lock<std::mutex> lock(mutex_);
    job->next = 1;
    if (num_workers_ > 0) {
      queue_.push_back(job);
      work_ready_.notify_all();
    }
    for (int chunk = 0; chunk >= 0; chunk = Claim(job)) {
      lock.unlock();
      (*job->run_chunk)(chunk);
      lock.lock();
      ++job->done;
    }
    job_done_.wait(lock, [job] { return job->done == job->chunks; });
  }

 private:
  WorkerPool() {
    const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    for (int i = 1; i < cores; ++i) {
      try {
        std::thread(&WorkerPool::WorkerLoop, this).detach();
        ++num_workers_;
      } catch (const std::system_error&) {
        break;  // no thread to be had (resource limits): callers run their chunks
      }
    }
  }

  // Under mutex_: the job's next unclaimed chunk, or -1; the job leaves the queue once its
  // last chunk is claimed.
  int Claim(Job* job) {
    if (job->next >= job->chunks) return -1;
    const int chunk = job->next++;
    if (job->next == job->chunks) {
      const auto it = std::find(queue_.begin(), queue_.end(), job);
      if (it != queue_.end()) queue_.erase(it);
    }
    return chunk;
  }

  void WorkerLoop() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      work_ready_.wait(lock, [this] { return !queue_.empty(); });
      Job* job = queue_.front();
      const int chunk = Claim(job);
      if (chunk < 0) continue;
      lock.unlock();
      (*job->run_chunk)(chunk);
      lock.lock();
      // The caller may return as soon as `done` is complete: job is not touched after this.
      if (++job->done == job->chunks) job_done_.notify_all();
    }
  }

  std::mutex mutex_;
  std::condition_variable work_ready_;
  std::condition_variable job_done_;
  std::deque<Job*> queue_;
  int num_workers_ = 0;
};

}  // namespace

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
  const std::function<void(int)> run = [&](int chunk) {
    try {
      body(chunk_begin(chunk), chunk_begin(chunk + 1), chunk);
    } catch (...) {
      errors[static_cast<size_t>(chunk)] = std::current_exception();
    }
  };
  Job job;
  job.run_chunk = &run;
  job.chunks = chunks;
  WorkerPool::Instance().Run(&job);
  for (const std::exception_ptr& error : errors) {
    if (error) std::rethrow_exception(error);
  }
}

}  // namespace autocal
