#pragma once

// The main of a benchmark program that times what a tool does: the process keeps freed memory
// and backs its heap with huge pages as the tools do (tools/keep_freed_memory.h), so its figures
// are the tools' own.

#include <benchmark/benchmark.h>

#include "tools/keep_freed_memory.h"

namespace autocal {
namespace bench {

inline int RunBenchmarksAsTheToolsDo(int argc, char** argv) {
  tools::StartWithHugePageHeap(argv);
  tools::KeepFreedMemory();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

}  // namespace bench
}  // namespace autocal
