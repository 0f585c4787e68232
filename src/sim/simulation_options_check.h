#pragma once

// The check of SimulationOptions every Simulator runs (simulation_options.cc).

#include "autocal/sim/simulator.h"

namespace autocal {
namespace sim {
namespace internal {

// Throws autocal::Error naming the first option out of its range (rates, noise, jitter,
// bursts, clock offsets, duration).
void ValidateSimulationOptions(const SimulationOptions& options);

}  // namespace internal
}  // namespace sim
}  // namespace autocal
