#include "autocal/common/parallel_for.h"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
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

TEST(ParallelForTest, ChunkCountIsBoundedByWorkAndThreads) {
  EXPECT_EQ(ParallelChunks(0, 4), 1);
  EXPECT_EQ(ParallelChunks(1, 4), 1);
  EXPECT_EQ(ParallelChunks(3, 4), 3);
  EXPECT_EQ(ParallelChunks(100, 4), 4);
  EXPECT_EQ(ParallelChunks(100, 0), 1);
}

TEST(ParallelForTest, RunsChunksConcurrently) {
  // Chunk 1 waits for chunk 0 to start: it would deadlock if the chunks ran one after the
  // other on the calling thread (chunk 0 runs there).
  std::atomic<bool> first_started{false};
  std::atomic<bool> second_done{false};
  ParallelFor(0, 2, 2, [&](int64_t, int64_t, int chunk) {
    if (chunk == 0) {
      first_started = true;
      while (!second_done) {
      }
    } else {
      while (!first_started) {
      }
      second_done = true;
    }
  });
  EXPECT_TRUE(second_done);
}

TEST(ParallelForTest, RethrowsTheFirstChunksExceptionAfterAllFinish) {
  std::atomic<int> finished{0};
  try {
    ParallelFor(0, 4, 4, [&](int64_t, int64_t, int chunk) {
      ++finished;
      if (chunk == 1) throw std::runtime_error("chunk 1");
      if (chunk == 3) throw std::runtime_error("chunk 3");
    });
    ADD_FAILURE() << "the exception must reach the caller";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "chunk 1");
  }
  EXPECT_EQ(finished, 4);
}

}  // namespace
}  // namespace autocal
