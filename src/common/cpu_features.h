#pragma once

// What the processor running the library can do, asked once, for the kernels that choose a
// vector path at run time (the library is built for the portable instruction set).

namespace autocal {
namespace internal {

// Whether AVX2 (and POPCNT, which every AVX2 processor has) may be used: x86 only.
bool CpuHasAvx2();

}  // namespace internal
}  // namespace autocal
