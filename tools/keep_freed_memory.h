#pragma once

// The tools stream whole logs: every sweep's file (hundreds of kilobytes), its clouds and the
// matrices built from them are allocated and freed again, hundreds of times. glibc's malloc
// maps large blocks on their own and trims the heap's free top, handing the memory back to the
// kernel, so that its reuse pays page faults and zeroing again: reading a 26k-point sweep took
// 4.1 ms on the development machine, 0.71 ms with freed memory kept. The tools keep it (the
// process stays near its peak size; the library itself leaves the allocator alone). A setting
// glibc refuses only leaves its default in place.

#include <cstdlib>
#include <cstring>
#include <string>

#if defined(__GLIBC__)
#include <malloc.h>
#include <unistd.h>
#endif

namespace autocal {
namespace tools {

// Transparent huge pages for the heap: with glibc's tunable glibc.malloc.hugetlb=1 (glibc 2.35
// and later) malloc advises the kernel to back the heap with 2 MiB pages. Calibrating the 60 s
// urban log then takes about 1 200 page faults instead of 60 000, and the 600 s log 9 800
// instead of a million and 63 s instead of 90 s (docs/calibration.md, "Speed"). glibc reads its
// tunables only when a process starts, so the tool runs itself again with the tunable added, once:
// the same process, program and arguments. It must be the first thing main does (nothing printed,
// no thread started). A GLIBC_TUNABLES that already names the tunable is left alone, and when the
// program cannot be run again it goes on as it is. GLIBC_TUNABLES=glibc.malloc.hugetlb=0 switches
// both off, e.g. under valgrind, which does not follow the new program unless told to
// (--trace-children=yes).
inline void StartWithHugePageHeap(char** argv) {
#if defined(__GLIBC__) && defined(__linux__)
  constexpr const char* kTunable = "glibc.malloc.hugetlb";
  constexpr const char* kRestarted = "AUTOCAL_HEAP_TUNED";  // guards against a second restart
  const char* given = std::getenv("GLIBC_TUNABLES");
  if (std::getenv(kRestarted) != nullptr ||
      (given != nullptr && std::strstr(given, kTunable) != nullptr)) {
    return;
  }
  const bool had_tunables = given != nullptr;
  const std::string tunables = had_tunables ? given : "";
  const std::string value =
      (tunables.empty() ? std::string() : tunables + ":") + std::string(kTunable) + "=1";
  if (setenv(kRestarted, "1", 1) == 0 && setenv("GLIBC_TUNABLES", value.c_str(), 1) == 0) {
    execv("/proc/self/exe", argv);
  }
  // Not run again: the environment goes back to what it was.
  unsetenv(kRestarted);
  if (had_tunables) {
    setenv("GLIBC_TUNABLES", tunables.c_str(), 1);
  } else {
    unsetenv("GLIBC_TUNABLES");
  }
#else
  (void)argv;
#endif
}

// Every block comes from the heap, none is mapped on its own, and the heap's free top is kept
// up to 2 GiB: a long log's solver matrices (Jacobians, normal equations and factors of hundreds
// of MiB, above glibc's largest mapping threshold) are reused by the next solve instead of being
// handed back to the kernel, faulted and zeroed again (docs/calibration.md, "Speed").
inline void KeepFreedMemory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_MAX, 0);
  mallopt(M_TRIM_THRESHOLD, 2047 << 20);
  mallopt(M_TOP_PAD, 64 << 20);  // the heap grown in 64 MiB steps
#endif
}

}  // namespace tools
}  // namespace autocal
