#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

#include "autocal/common/time.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/output_files.h"
#include "autocal/io/tum_trajectory.h"
#include "autocal/pipeline/online_estimation.h"
#include "autocal/sensors/calibration_blocks.h"

// The files autocal_estimate writes (README.md, its row of the tools table): the calibration,
// the trajectories, states.csv, calibration_over_time.csv and the timings.

namespace autocal {
namespace pipeline {

namespace {

// states.csv: per keyframe its time, pose, velocity and biases.
void WriteStatesCsv(const std::string& path,
                    const std::vector<estimation::SlidingWindowState>& states) {
  std::ostringstream csv;
  csv << "t_s,p_W_I_x_m,p_W_I_y_m,p_W_I_z_m,q_W_I_x,q_W_I_y,q_W_I_z,q_W_I_w,"
         "v_W_I_x_m_s,v_W_I_y_m_s,v_W_I_z_m_s,b_g_x_rad_s,b_g_y_rad_s,b_g_z_rad_s,"
         "b_a_x_m_s2,b_a_y_m_s2,b_a_z_m_s2\n";
  csv << std::setprecision(12);
  for (const estimation::SlidingWindowState& x : states) {
    csv << FormatSeconds(x.t_ns);
    const auto row = [&csv](const auto& v) {
      for (int i = 0; i < v.size(); ++i) csv << ',' << v[i];
    };
    row(x.p_W_I);
    row(x.q_W_I.coeffs());
    row(x.v_W_I);
    row(x.b_g);
    row(x.b_a);
    csv << '\n';
  }
  io::WriteFileAtomically(path, csv.str());
}

// calibration_over_time.csv: the keyframe time, then the blocks' values in table order.
std::string CalibrationOverTimeCsv(const std::vector<CalibrationSample>& samples) {
  std::ostringstream csv;
  csv << "t_s";
  for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
    for (const std::string& column : sensors::ValueColumns(block)) csv << ',' << column;
  }
  csv << '\n' << std::setprecision(12);
  for (const CalibrationSample& s : samples) {
    csv << FormatSeconds(s.t_ns);
    for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
      const double* values = block.const_values(s.calibration);
      for (int k = 0; k < block.ambient_size; ++k) csv << ',' << values[k];
    }
    csv << '\n';
  }
  return csv.str();
}

}  // namespace

void WriteOnlineEstimationResult(const std::string& directory,
                                 const OnlineEstimationResult& result) {
  io::StagedDirectory out(directory, io::OutputKind::kResult);
  io::WriteCalibrationYaml(out.File("calibration.yaml"), result.calibration);
  io::WriteTumTrajectory(out.File("trajectory.tum"), result.trajectory);
  if (!result.smoothed_trajectory.empty()) {
    io::WriteTumTrajectory(out.File("trajectory_smoothed.tum"), result.smoothed_trajectory);
  }
  WriteStatesCsv(out.File("states.csv"), result.states);
  io::WriteFileAtomically(out.File("calibration_over_time.csv"),
                          CalibrationOverTimeCsv(result.calibration_over_time));
  std::ostringstream timings;
  timings << "# autocal_estimate wall-clock seconds (differ from run to run)\n"
          << "seconds_total: " << result.seconds_total << "\n"
          << "seconds_initialization: " << result.seconds_initialization << "\n";
  io::WriteFileAtomically(out.File("timings.yaml"), timings.str());
  io::WriteWarningsFile(out.File("warnings.txt"), result.warnings);
  out.Commit();
}

}  // namespace pipeline
}  // namespace autocal
