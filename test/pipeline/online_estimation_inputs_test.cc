// The online estimator's checks that a sensor the problem uses reaches the sliding window
// (src/pipeline/calibration_steps.h), on hand-made sample lists.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <string>

#include "autocal/common/error.h"
#include "autocal/io/dataset.h"
#include "pipeline/calibration_steps.h"

namespace autocal {
namespace pipeline {
namespace {

using ::testing::HasSubstr;

constexpr int64_t kStartNs = 1'700'000'000'000'000'000;

// 100 Hz wheels and 10 Hz fixes over the first `duration_s` seconds.
io::Dataset Logged(double duration_s) {
  io::Dataset dataset;
  dataset.directory = "/data/run7";
  for (int64_t t = 0; t <= static_cast<int64_t>(duration_s * 1e9); t += 10'000'000) {
    sensors::WheelSample w;
    w.t_ns = kStartNs + t;
    dataset.wheel.push_back(w);
    if (t % 100'000'000 == 0) {
      sensors::GnssFix fix;
      fix.t_ns = kStartNs + t;
      dataset.gnss.push_back(fix);
    }
  }
  return dataset;
}

// Wheels logged only while the online estimator initializes (the first 2 s here): the window,
// which starts at 3 s, would never see one, and the result would silently leave them out.
TEST(OnlineEstimationInputs, RefusesSensorsWithNoSampleAfterTheInitialState) {
  const io::Dataset dataset = Logged(2.0);
  const int64_t t0_ns = kStartNs + 3'000'000'000;
  try {
    RequireSamplesAfter(dataset, true, false, t0_ns);
    FAIL() << "wheels that end before the initial state were accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "dataset /data/run7: wheel.csv: 0 of 201 samples after the online estimator's "
              "initial state at 1700000003000000000 ns (the log's last is at "
              "1700000002000000000 ns); nothing was estimated");
  }
  EXPECT_THROW(RequireSamplesAfter(dataset, false, true, t0_ns), Error);
  // Unused sensors, or samples after the initial state, pass.
  EXPECT_NO_THROW(RequireSamplesAfter(dataset, false, false, t0_ns));
  EXPECT_NO_THROW(RequireSamplesAfter(dataset, true, true, kStartNs + 1'000'000'000));
}

TEST(OnlineEstimationInputs, RefusesSensorsTheWindowAcceptedNothingFrom) {
  const io::Dataset dataset = Logged(5.0);
  estimation::SlidingWindowCounters counters;
  counters.wheel_accepted = 380;
  counters.gnss_accepted = 0;  // every fix late or out of order
  try {
    RequireStreamedSamples(dataset, true, true, counters);
    FAIL() << "a run whose fixes never reached the window was accepted";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("no GNSS sample reached the sliding window (gnss.csv: 0 of "
                                    "51 samples"));
  }
  EXPECT_NO_THROW(RequireStreamedSamples(dataset, true, false, counters));
  counters.wheel_accepted = 0;
  EXPECT_THROW(RequireStreamedSamples(dataset, true, false, counters), Error);
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
