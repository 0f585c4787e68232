#include "autocal/sim/scenario.h"

#include <random>
#include <string>

#include "autocal/common/error.h"
#include "scenario_parts.h"

namespace autocal {
namespace sim {

std::string ScenarioName(ScenarioType type) {
  switch (type) {
    case ScenarioType::kUrban:
      return "urban";
    case ScenarioType::kHighway:
      return "highway";
    case ScenarioType::kSkidSteer:
      return "skid_steer";
    case ScenarioType::kStraight:
      return "straight";
  }
  return "unknown";
}

ScenarioType ParseScenarioType(const std::string& name) {
  for (ScenarioType type : {ScenarioType::kUrban, ScenarioType::kHighway, ScenarioType::kSkidSteer,
                            ScenarioType::kStraight}) {
    if (name == ScenarioName(type)) return type;
  }
  throw Error("unknown scenario '" + name + "' (expected urban, highway, skid_steer or straight)");
}

Scenario BuildScenario(const ScenarioOptions& options) {
  if (!(options.duration_s > 0.0) || options.duration_s > 3600.0) {
    throw Error("simulated scenario: duration must be in (0, 3600] s, got " +
                std::to_string(options.duration_s));
  }
  std::mt19937_64 rng(options.seed * 0x9E3779B97F4A7C15ull + 17);
  switch (options.type) {
    case ScenarioType::kUrban:
      return internal::BuildUrban(options, &rng);
    case ScenarioType::kHighway:
      return internal::BuildHighway(options, &rng);
    case ScenarioType::kSkidSteer:
      return internal::BuildSkidSteer(options, &rng);
    case ScenarioType::kStraight:
      return internal::BuildStraight(options, &rng);
  }
  throw Error("simulated scenario: unknown type");
}

}  // namespace sim
}  // namespace autocal
