#pragma once

// The tools stream whole logs: every sweep's file (hundreds of kilobytes), its clouds and the
// matrices built from them are allocated and freed again, hundreds of times. glibc's malloc
// maps large blocks on their own and trims the heap's free top, handing the memory back to the
// kernel, so that its reuse pays page faults and zeroing again: reading a 26k-point sweep took
// 4.1 ms on the development machine, 0.71 ms with freed memory kept. The tools keep it (the
// process stays near its peak size; the library itself leaves the allocator alone). A setting
// glibc refuses only leaves its default in place.

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace autocal {
namespace tools {

inline void KeepFreedMemory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 32 << 20);   // blocks below 32 MiB (glibc's largest) on the heap
  mallopt(M_TRIM_THRESHOLD, 256 << 20);  // the heap's free top kept up to 256 MiB
  mallopt(M_TOP_PAD, 64 << 20);          // and grown in 64 MiB steps
#endif
}

}  // namespace tools
}  // namespace autocal
