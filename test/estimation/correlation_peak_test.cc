#include "estimation/correlation_peak.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <tuple>
#include <vector>

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {
namespace internal {
namespace {

double NegativeSquare(double offset_s) { return -(offset_s - 0.01) * (offset_s - 0.01); }

// Every candidate lies within the half range of the centre: a step that does not divide the
// range ends at the last whole step (0.1 / 0.006: 16 steps, 0.096 s; rounding the count took
// 17, 0.102 s, past the range the caller had checked); one that divides it up to rounding
// (0.1 / 0.001) keeps its end.
TEST(ScanCorrelation, StaysInsideTheHalfRange) {
  const CorrelationScan uneven = ScanCorrelation(0.5, 0.1, 0.006, NegativeSquare);
  ASSERT_EQ(uneven.offsets_s.size(), 33u);
  EXPECT_NEAR(uneven.offsets_s.front(), 0.404, 1e-12);
  EXPECT_NEAR(uneven.offsets_s.back(), 0.596, 1e-12);
  for (double offset_s : uneven.offsets_s) EXPECT_LE(std::abs(offset_s - 0.5), 0.1);
  for (double step_s : {0.001, 0.01, 0.02, 0.05, 0.1}) {
    const CorrelationScan even = ScanCorrelation(0.0, 0.1, step_s, NegativeSquare);
    EXPECT_EQ(even.offsets_s.size(), 2 * static_cast<size_t>(std::lround(0.1 / step_s)) + 1)
        << step_s;
    EXPECT_NEAR(even.offsets_s.back(), 0.1, 1e-12) << step_s;
  }
  const CorrelationScan fine = ScanCorrelation(0.0, 0.1, 0.001, NegativeSquare);
  EXPECT_FALSE(fine.peak_at_edge);
  EXPECT_NEAR(fine.refined_offset_s, 0.01, 1e-9);
}

// A negative half range left the curve empty and read past its end (a crash); a zero,
// negative or infinite step overflowed the step count; a step longer than the half range
// scans the centre alone. Each is refused by name, as is a grid of more than a million steps
// either side.
TEST(ScanCorrelation, RefusesARangeOrStepThatIsNotAPositiveDuration) {
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::nan("");
  const std::vector<std::tuple<double, double, double, std::string>> cases = {
      {0.0, -0.1, 0.001, "half range must be finite and positive"},
      {0.0, 0.0, 0.001, "half range must be finite and positive"},
      {0.0, nan, 0.001, "half range must be finite and positive"},
      {0.0, inf, 0.001, "half range must be finite and positive"},
      {0.0, 0.1, 0.0, "step must be finite and positive"},
      {0.0, 0.1, -0.001, "step must be finite and positive"},
      {0.0, 0.1, inf, "step must be finite and positive"},
      {0.0, 0.1, nan, "step must be finite and positive"},
      {0.0, 0.1, 0.2, "step must not exceed the half range"},
      {0.0, 10.0, 1e-6, "at most 1000000 steps either side"},
      {nan, 0.1, 0.001, "centre must be finite"},
  };
  for (const auto& [center_s, half_range_s, step_s, expected] : cases) {
    int evaluations = 0;
    try {
      ScanCorrelation(center_s, half_range_s, step_s, [&](double offset_s) {
        ++evaluations;
        return NegativeSquare(offset_s);
      });
      ADD_FAILURE() << "half range " << half_range_s << ", step " << step_s << " accepted";
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_EQ(message.rfind("ScanCorrelation: ", 0), 0u) << message;
      EXPECT_NE(message.find(expected), std::string::npos) << message;
    }
    EXPECT_EQ(evaluations, 0);
  }
}

}  // namespace
}  // namespace internal
}  // namespace estimation
}  // namespace autocal
