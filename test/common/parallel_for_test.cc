#include "autocal/common/parallel_for.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace autocal {
namespace {

TEST(ParallelForTest, VisitsEveryIndexOnceInContiguousChunks) {
  for (int threads : {1, 2, 3, 8}) {
    for (int64_t count : {0, 1, 2, 7, 1000}) {
      std::vector<int> visits(static_cast<size_t>(count), 0);
      std::vector<int> chunk_of(static_cast<size_t>(count), -1);
      ParallelFor(5, 5 + count, threads, [&](int64_t begin, int64_t end, int chunk) {
        for (int64_t i = begin; i < end; ++i) {
          ++visits[static_cast<size_t>(i - 5)];
          chunk_of[static_cast<size_t>(i - 5)] = chunk;
        }
      });
      for (int64_t i = 0; i < count; ++i) {
        EXPECT_EQ(visits[static_cast<size_t>(i)], 1) << threads << " threads, index " << i;
        // Chunks are in order: chunk numbers never decrease along the range.
        if (i > 0) {
          EXPECT_LE(chunk_of[static_cast<size_t>(i - 1)], chunk_of[static_cast<size_t>(i)]);
        }
        EXPECT_LT(chunk_of[static_cast<size_t>(i)], ParallelChunks(count, threads));
      }
    }
  }
}

TEST(ParallelForTest, ChunkCountIsBoundedByWorkThreadsAndCores) {
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  EXPECT_EQ(ParallelChunks(0, 4), 1);
  EXPECT_EQ(ParallelChunks(1, 4), 1);
  EXPECT_EQ(ParallelChunks(3, 4), std::min(3, cores));
  EXPECT_EQ(ParallelChunks(100, 4), std::min(4, cores));
  EXPECT_EQ(ParallelChunks(100, 1000), cores);
  EXPECT_EQ(ParallelChunks(100, 0), 1);
}

TEST(ParallelForTest, RunsChunksConcurrently) {
  if (ParallelChunks(2, 2) < 2) GTEST_SKIP() << "one core: the chunks run one after the other";
  // Chunk 0 (on the calling thread) waits for chunk 1 to run: if the chunks ran one after
  // the other it would give up after the deadline and the test fails.
  std::atomic<bool> second_done{false};
  bool waited_out = false;
  ParallelFor(0, 2, 2, [&](int64_t, int64_t, int chunk) {
    if (chunk == 1) {
      second_done = true;
      return;
    }
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (!second_done) {
      if (std::chrono::steady_clock::now() > deadline) {
        waited_out = true;
        return;
      }
      std::this_thread::yield();
    }
  });
  EXPECT_FALSE(waited_out) << "chunk 1 did not run while chunk 0 was running";
}

TEST(ParallelForTest, RethrowsTheFirstChunksExceptionAfterAllFinish) {
  const int chunks = ParallelChunks(1000, 8);
  // Every chunk but the first throws (the only one does, on one core).
  const int first_thrower = chunks > 1 ? 1 : 0;
  std::atomic<int> finished{0};
  try {
    ParallelFor(0, 1000, 8, [&](int64_t, int64_t, int chunk) {
      ++finished;
      if (chunk >= first_thrower) throw std::runtime_error("chunk " + std::to_string(chunk));
    });
    ADD_FAILURE() << "the exception must reach the caller";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "chunk " + std::to_string(first_thrower));
  }
  EXPECT_EQ(finished, chunks);
}

TEST(ParallelForTest, RunsChunkZeroOnTheCaller) {
  const std::thread::id caller = std::this_thread::get_id();
  std::thread::id chunk_zero;
  ParallelFor(0, 100, 8, [&](int64_t, int64_t, int chunk) {
    if (chunk == 0) chunk_zero = std::this_thread::get_id();
  });
  EXPECT_EQ(chunk_zero, caller);
}

// A ParallelFor inside every chunk of another, from several threads at once, so that the
// pool's workers are all busy: each call still finishes, visiting every index once.
TEST(ParallelForTest, NestedAndConcurrentCallsComplete) {
  constexpr int kOuter = 64;
  constexpr int kInner = 1000;
  const auto nested_sum = [&]() {
    std::atomic<int64_t> sum{0};
    ParallelFor(0, kOuter, 8, [&](int64_t begin, int64_t end, int) {
      for (int64_t i = begin; i < end; ++i) {
        ParallelFor(0, kInner, 8, [&](int64_t b, int64_t e, int) {
          for (int64_t j = b; j < e; ++j) sum += j;
        });
      }
    });
    return sum.load();
  };
  const int64_t expected = int64_t{kOuter} * kInner * (kInner - 1) / 2;
  std::vector<int64_t> sums(4);
  std::vector<std::thread> callers;
  for (size_t t = 0; t < sums.size(); ++t) callers.emplace_back([&, t] { sums[t] = nested_sum(); });
  for (std::thread& caller : callers) caller.join();
  for (const int64_t sum : sums) EXPECT_EQ(sum, expected);
}

}  // namespace
}  // namespace autocal
