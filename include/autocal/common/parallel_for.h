#pragma once

// A minimal fork-join loop for the library's data-parallel kernels (nearest-neighbour
// searches, normals, residual accumulation). Work is split into num_threads contiguous
// chunks of [begin, end); chunk 0 runs on the calling thread, so num_threads = 1 costs
// nothing and runs inline, and the others on a process-wide pool of one worker per further
// core (started on first use; a call costs about 14 us instead of a thread start's 55 us).
// The chunks follow the thread count: a sum that must not depend on it is taken over fixed
// blocks of items, combined in block order (as lidar/icp.cc does).

#include <cstdint>
#include <functional>

namespace autocal {

// The number of chunks ParallelFor uses for `count` items on `num_threads` threads: at
// least 1, at most count, never more than requested nor than the machine's cores.
int ParallelChunks(int64_t count, int num_threads);

// Calls body(chunk_begin, chunk_end, chunk) for every chunk, concurrently, and returns
// when all have finished. Chunks no worker has taken (none could be started, or all are
// busy, e.g. in a ParallelFor inside a chunk) run on the calling thread. An exception thrown by a
// body is rethrown on the caller after every chunk has finished (the first one, by chunk order).
void ParallelFor(int64_t begin, int64_t end, int num_threads,
                 const std::function<void(int64_t, int64_t, int)>& body);

}  // namespace autocal
