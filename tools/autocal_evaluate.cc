// autocal_evaluate: compares a calibration result (and its trajectory) with a dataset's ground
// truth, prints the errors, writes RESULT/evaluation.yaml and checks the given limits.
// See docs/evaluation.md.

#include <gflags/gflags.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/evaluation/evaluation.h"
#include "autocal/io/output_files.h"
#include "tool_help.h"

DECLARE_bool(help);
DECLARE_bool(helpshort);
DECLARE_string(helpon);

DEFINE_string(dataset, "",
              "dataset directory: reads groundtruth/calibration.yaml and, for the ATE, "
              "groundtruth/trajectory.csv (required)");
DEFINE_string(result, "",
              "result directory: reads calibration.yaml and, when present, trajectory.tum (TUM "
              "format, T_W_I on the IMU clock); writes evaluation.yaml (required)");
DEFINE_string(trajectory, "trajectory.tum",
              "trajectory file of RESULT to evaluate (e.g. trajectory_smoothed.tum, written by "
              "autocal_estimate beside the filtered trajectory.tum)");
DEFINE_string(max_rotation_deg, "",
              "limit (unset: not checked) on the T_I_L rotation error angle, degrees");
DEFINE_string(max_translation_mm, "",
              "limit (unset: not checked) on the T_I_L translation error, millimetres");
DEFINE_string(max_time_offset_ms, "",
              "limit (unset: not checked) on the LiDAR-IMU time offset error, milliseconds");
DEFINE_string(max_radius_percent, "",
              "limit (unset: not checked) on each wheel radius' relative error, percent");
DEFINE_string(max_track_width_percent, "",
              "limit (unset: not checked) on the track width's relative error, percent");
DEFINE_string(max_lever_arm_mm, "",
              "limit (unset: not checked) on the GNSS lever arm p_I_A error, millimetres");
DEFINE_string(max_vehicle_rotation_deg, "",
              "limit (unset: not checked) on the T_I_V rotation error angle, degrees");
DEFINE_string(max_vehicle_translation_mm, "",
              "limit (unset: not checked) on the T_I_V translation error, millimetres");
DEFINE_string(max_speed_scale_percent, "",
              "limit (unset: not checked) on each wheel speed scale's and the odometry speed "
              "scale's relative error, percent");
DEFINE_string(max_effective_track_percent, "",
              "limit (unset: not checked) on the effective track's relative error, percent");
DEFINE_string(max_wheel_time_offset_ms, "",
              "limit (unset: not checked) on the wheel-IMU clock offset error, milliseconds");
DEFINE_string(max_gnss_time_offset_ms, "",
              "limit (unset: not checked) on the GNSS-IMU clock offset error, milliseconds");
DEFINE_string(max_ate_m, "",
              "limit (unset: not checked) on the trajectory ATE translation RMSE after 4-DoF "
              "alignment, metres "
              "(needs RESULT/trajectory.tum)");
DEFINE_string(
    max_ate_deg, "",
    "limit (unset: not checked) on the trajectory ATE rotation RMSE after 4-DoF alignment, degrees "
    "(needs RESULT/trajectory.tum)");
DEFINE_string(
    max_interpolation_gap_s, "0.1",
    "an estimated pose between two ground-truth samples at most this far apart is "
    "compared with their interpolation; other unmatched poses are left out (0: exact stamps only)");

namespace {

constexpr int kExitPassed = 0;
constexpr int kExitExceeded = 1;
constexpr int kExitBadInput = 2;

// Numbers are parsed here rather than by gflags, which would exit with status 1 on a bad
// value: this tool reserves 1 for exceeded limits.
double NonNegativeNumber(const char* flag, const std::string& text) {
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(value) || value < 0.0) {
    throw autocal::Error(std::string("--") + flag + " must be a number >= 0, got '" + text + "'");
  }
  return value;
}

// A limit is checked only when its flag is given (non-empty).
std::optional<double> Limit(const char* flag, const std::string& text) {
  if (text.empty()) return std::nullopt;
  return NonNegativeNumber(flag, text);
}

// The first argument that names no flag of this program, or empty. gflags would exit with
// status 1 on it.
std::string UnknownFlag(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--") break;
    if (arg.size() < 2 || arg[0] != '-') continue;
    std::string name = arg.substr(arg[1] == '-' ? 2 : 1);
    name = name.substr(0, name.find('='));
    gflags::CommandLineFlagInfo info;
    if (gflags::GetCommandLineFlagInfo(name.c_str(), &info)) continue;
    // --nofoo sets the boolean flag foo to false.
    if (name.rfind("no", 0) == 0 && gflags::GetCommandLineFlagInfo(name.c_str() + 2, &info) &&
        info.type == "bool") {
      continue;
    }
    return arg;
  }
  return "";
}

autocal::evaluation::Thresholds ThresholdsFromFlags() {
  autocal::evaluation::Thresholds t;
  t.max_rotation_deg = Limit("max_rotation_deg", FLAGS_max_rotation_deg);
  t.max_translation_mm = Limit("max_translation_mm", FLAGS_max_translation_mm);
  t.max_time_offset_ms = Limit("max_time_offset_ms", FLAGS_max_time_offset_ms);
  t.max_radius_percent = Limit("max_radius_percent", FLAGS_max_radius_percent);
  t.max_track_width_percent = Limit("max_track_width_percent", FLAGS_max_track_width_percent);
  t.max_lever_arm_mm = Limit("max_lever_arm_mm", FLAGS_max_lever_arm_mm);
  t.max_vehicle_rotation_deg = Limit("max_vehicle_rotation_deg", FLAGS_max_vehicle_rotation_deg);
  t.max_vehicle_translation_mm =
      Limit("max_vehicle_translation_mm", FLAGS_max_vehicle_translation_mm);
  t.max_speed_scale_percent = Limit("max_speed_scale_percent", FLAGS_max_speed_scale_percent);
  t.max_effective_track_percent =
      Limit("max_effective_track_percent", FLAGS_max_effective_track_percent);
  t.max_wheel_time_offset_ms = Limit("max_wheel_time_offset_ms", FLAGS_max_wheel_time_offset_ms);
  t.max_gnss_time_offset_ms = Limit("max_gnss_time_offset_ms", FLAGS_max_gnss_time_offset_ms);
  t.max_ate_m = Limit("max_ate_m", FLAGS_max_ate_m);
  t.max_ate_deg = Limit("max_ate_deg", FLAGS_max_ate_deg);
  return t;
}

int Run() {
  using autocal::Error;
  namespace evaluation = autocal::evaluation;
  if (FLAGS_dataset.empty()) throw Error("--dataset=DIR is required");
  if (FLAGS_result.empty()) throw Error("--result=DIR is required");
  const double max_gap_s =
      NonNegativeNumber("max_interpolation_gap_s", FLAGS_max_interpolation_gap_s);
  const evaluation::Thresholds thresholds = ThresholdsFromFlags();
  if (FLAGS_trajectory.empty()) throw Error("--trajectory must name a file of RESULT");
  std::error_code error;
  if (!std::filesystem::is_directory(FLAGS_result, error)) {
    throw Error("--result: '" + FLAGS_result + "' does not exist or is not a directory");
  }
  evaluation::ResultPaths paths = evaluation::ResultPaths::For(FLAGS_dataset, FLAGS_result);
  paths.result_trajectory = (std::filesystem::path(FLAGS_result) / FLAGS_trajectory).string();
  autocal::io::CheckOutputFile(paths.evaluation);
  evaluation::TrajectoryErrorOptions options;
  options.max_interpolation_gap_s = max_gap_s;
  const evaluation::Evaluation result = evaluation::EvaluateResult(paths, options);
  gflags::CommandLineFlagInfo trajectory_flag;
  if (!result.trajectory && gflags::GetCommandLineFlagInfo("trajectory", &trajectory_flag) &&
      !trajectory_flag.is_default) {
    throw Error("--trajectory: '" + paths.result_trajectory + "' does not exist");
  }
  if (!result.trajectory && (thresholds.max_ate_m || thresholds.max_ate_deg)) {
    throw Error("--max_ate_m/--max_ate_deg need an estimated trajectory, but '" +
                paths.result_trajectory + "' does not exist");
  }
  // Checks the limits (and rejects negative ones) before anything is printed or written.
  const std::vector<evaluation::ThresholdViolation> violations =
      evaluation::ExceededThresholds(result, thresholds);
  std::printf("%s", evaluation::FormatEvaluationTable(result, thresholds).c_str());
  // Replaced atomically: a stopped run leaves the previous evaluation.yaml or none.
  autocal::io::WriteFileAtomically(paths.evaluation,
                                   evaluation::EvaluationYamlText(result, thresholds));
  std::printf("wrote %s\n", paths.evaluation.c_str());
  if (violations.empty()) {
    std::printf("PASSED: every given limit holds\n");
    return kExitPassed;
  }
  std::printf("FAILED: %zu limit(s) exceeded\n", violations.size());
  for (const evaluation::ThresholdViolation& v : violations)
    std::printf("  %s\n", v.ToString().c_str());
  return kExitExceeded;
}

}  // namespace

int main(int argc, char** argv) {
  gflags::SetUsageMessage(
      "compares a calibration result with a dataset's ground truth\n"
      "  autocal_evaluate --dataset=DIR --result=DIR [--max_rotation_deg=0.5 ...]\n"
      "Prints the error of every calibration block (T_I_L, time offset, wheel radii, track\n"
      "width, speed scales, effective track, lever arm, T_I_V, the wheel and GNSS clocks; a\n"
      "block the result did not estimate shows as such, and a limit on it fails) and, when\n"
      "RESULT/trajectory.tum (or --trajectory) exists, the\n"
      "ATE after a 4-DoF (yaw + translation) alignment; writes RESULT/evaluation.yaml. A\n"
      "--max_* limit is checked only when given. Exit status: 0 every given limit holds, 1 some\n"
      "limit is exceeded (each is named), 2 bad input (flags, missing or malformed files).");
  if (autocal::tools::ShowShortHelpIfAsked(argc, argv, "autocal_evaluate")) return 0;
  const std::string unknown = UnknownFlag(argc, argv);
  if (!unknown.empty()) {
    std::fprintf(stderr, "autocal_evaluate: unknown flag '%s' (see --help)\n", unknown.c_str());
    return kExitBadInput;
  }
  gflags::ParseCommandLineNonHelpFlags(&argc, &argv, true);
  if (FLAGS_help || FLAGS_helpshort || !FLAGS_helpon.empty()) {
    gflags::ShowUsageWithFlagsRestrict(argv[0], "autocal_evaluate");
    return kExitPassed;
  }
  gflags::HandleCommandLineHelpFlags();
  try {
    if (argc > 1) throw autocal::Error(std::string("unexpected argument '") + argv[1] + "'");
    return Run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autocal_evaluate: %s\n", e.what());
    return kExitBadInput;
  }
}
