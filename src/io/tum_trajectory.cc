#include "autocal/io/tum_trajectory.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "io/byte_source.h"
#include "io/text_format.h"

namespace autocal {
namespace io {
namespace {

using internal::Quote;
using internal::Word;

constexpr int kTumColumns = 8;

// A file written by WriteTumTrajectory opens with this line and closes with "# end: <N>
// poses" and a line break; both are TUM comments, which evo and other readers skip.
constexpr std::string_view kHeader = "# autocal_trajectory_1 timestamp tx ty tz qx qy qz qw";
constexpr std::string_view kEndPrefix = "# end: ";
constexpr std::string_view kEndSuffix = " poses";

std::string EndLine(size_t poses) {
  return std::string(kEndPrefix) + std::to_string(poses) + std::string(kEndSuffix);
}

// The pose count of an end line "# end: <N> poses", or -1 when `line` is not one.
int64_t EndLineCount(std::string_view line) {
  if (line.size() <= kEndPrefix.size() + kEndSuffix.size() ||
      line.substr(0, kEndPrefix.size()) != kEndPrefix ||
      line.substr(line.size() - kEndSuffix.size()) != kEndSuffix) {
    return -1;
  }
  const std::string_view digits =
      line.substr(kEndPrefix.size(), line.size() - kEndPrefix.size() - kEndSuffix.size());
  int64_t count = 0;
  std::string why;
  if (!internal::ParseInt64(digits, &count, &why) || count < 0) return -1;
  return count;
}

// A timestamp in seconds -> nanoseconds, exactly (no detour through double): decimal
// ("1700000000.123456789", any number of decimals) or scientific notation as numpy writes it
// ("1.403636579763555527e+09", evo's default). Digits finer than a nanosecond round to the
// nearest one (half away from zero).
bool ParseSecondsToNs(std::string_view text, int64_t* t_ns, std::string* why) {
  const auto fail = [&](const std::string& what) {
    *why = what;
    return false;
  };
  const std::string expected = "expected a timestamp in seconds, found " + Quote(text);
  size_t at = 0;
  bool negative = false;
  if (!text.empty() && (text[0] == '-' || text[0] == '+')) {
    negative = text[0] == '-';
    at = 1;
  }
  // The mantissa's digits, and how many of them follow its point.
  std::string digits;
  int64_t decimals = 0;
  bool point = false;
  for (; at < text.size(); ++at) {
    const char c = text[at];
    if (c >= '0' && c <= '9') {
      digits += c;
      decimals += point ? 1 : 0;
    } else if (c == '.' && !point) {
      point = true;
    } else {
      break;
    }
  }
  if (digits.empty()) return fail(expected);
  int64_t exponent = 0;
  if (at < text.size() && (text[at] == 'e' || text[at] == 'E')) {
    if (!internal::ParseInt64(text.substr(at + 1), &exponent, why) || exponent > 100 ||
        exponent < -100) {
      return fail(expected);
    }
    at = text.size();
  }
  if (at != text.size()) return fail(expected);
  // ns = digits * 10^shift.
  const int64_t shift = exponent - decimals + 9;
  const std::string too_large = "timestamp " + Quote(text) + " does not fit in int64 nanoseconds";
  if (shift >= 0) {
    if (static_cast<int64_t>(digits.size()) + shift > 40) return fail(too_large);
    digits.append(static_cast<size_t>(shift), '0');
  }
  const size_t kept =
      shift >= 0
          ? digits.size()
          : static_cast<size_t>(std::max<int64_t>(0, static_cast<int64_t>(digits.size()) + shift));
  const bool round_up = kept < digits.size() && digits[kept] >= '5';
  constexpr int64_t kMax = std::numeric_limits<int64_t>::max();
  int64_t ns = 0;
  for (size_t i = 0; i < kept; ++i) {
    const int digit = digits[i] - '0';
    if (ns > (kMax - digit) / 10) return fail(too_large);
    ns = ns * 10 + digit;
  }
  if (round_up) {
    if (ns == kMax) return fail(too_large);
    ++ns;
  }
  *t_ns = negative ? -ns : ns;
  return true;
}

}  // namespace

void WriteTumTrajectory(const std::string& path, const Trajectory& trajectory) {
  std::string text = std::string(kHeader) + "\n";
  for (size_t i = 0; i < trajectory.size(); ++i) {
    const TrajectorySample& s = trajectory[i];
    if (i > 0 && s.t_ns <= trajectory[i - 1].t_ns) {
      throw Error("cannot write '" + path + "': pose " + std::to_string(i) +
                  " does not follow the previous one in time");
    }
    const Eigen::Quaterniond& q = s.T_W_I.q;
    const double values[7] = {s.T_W_I.p.x(), s.T_W_I.p.y(), s.T_W_I.p.z(), q.x(),
                              q.y(),         q.z(),         q.w()};
    text += FormatSeconds(s.t_ns);
    for (double value : values) {
      if (!std::isfinite(value)) {
        throw Error("cannot write '" + path + "': pose " + std::to_string(i) + " is not finite");
      }
      text += ' ';
      text += internal::FormatDouble(value);
    }
    text += '\n';
  }
  text += EndLine(trajectory.size()) + "\n";
  internal::WriteFileText(path, text);
}

Trajectory ReadTumTrajectory(const std::string& path) {
  const std::string bytes = internal::ReadFileBytes(path);
  internal::ByteSource source(path, bytes);
  if (bytes.empty()) source.FailAtByte(0, "the file is empty: expected TUM poses");
  Trajectory trajectory;
  int64_t previous_line = 0;
  // Whole-file checks of a file this library wrote (kHeader on its first line).
  const bool written_here = bytes.compare(0, kHeader.size() + 1, std::string(kHeader) + "\n") == 0;
  int64_t end_line = 0;
  std::string_view line;
  while (source.NextLine(&line)) {
    const std::string_view trimmed = internal::Trim(line);
    if (written_here && end_line > 0 && !trimmed.empty()) {
      source.FailAtColumn(1, "text after the end line (line " + std::to_string(end_line) + ")");
    }
    if (written_here && EndLineCount(line) >= 0) {
      if (EndLineCount(line) != static_cast<int64_t>(trajectory.size())) {
        source.FailAtColumn(1, "the end line counts " + std::to_string(EndLineCount(line)) +
                                   " poses, but the file holds " +
                                   std::to_string(trajectory.size()));
      }
      end_line = source.line();
      continue;
    }
    if (trimmed.empty() || trimmed[0] == '#') continue;
    const std::vector<Word> fields = internal::SplitWords(line);
    if (fields.size() != kTumColumns) {
      const int64_t column = fields.size() > kTumColumns ? fields[kTumColumns].column
                                                         : static_cast<int64_t>(line.size()) + 1;
      source.FailAtColumn(column, "expected 8 values 'timestamp tx ty tz qx qy qz qw', found " +
                                      std::to_string(fields.size()));
    }
    TrajectorySample sample;
    std::string why;
    if (!ParseSecondsToNs(fields[0].text, &sample.t_ns, &why))
      source.FailAtColumn(fields[0].column, why);
    if (!trajectory.empty() && sample.t_ns <= trajectory.back().t_ns) {
      source.FailAtColumn(
          fields[0].column,
          std::string(sample.t_ns == trajectory.back().t_ns ? "duplicate" : "non-monotonic") +
              " timestamp: the previous pose (line " + std::to_string(previous_line) +
              ") is not earlier; timestamps must strictly increase");
    }
    double values[7];
    for (int i = 0; i < 7; ++i) {
      if (!internal::ParseFiniteDouble(fields[1 + i].text, &values[i], &why)) {
        source.FailAtColumn(fields[1 + i].column, why);
      }
    }
    Eigen::Vector4d xyzw(values[3], values[4], values[5], values[6]);
    const double norm = xyzw.norm();
    if (std::abs(norm - 1.0) > 1e-3) {
      char buffer[160];
      std::snprintf(
          buffer, sizeof(buffer),
          "quaternion (qx qy qz qw) has norm %.6g, not a rotation (|norm - 1| must be <= 1e-3)",
          norm);
      source.FailAtColumn(fields[4].column, buffer);
    }
    // Below 1e-15, |q| - 1 is rounding: keep the digits so that files round trip exactly.
    if (std::abs(norm - 1.0) > 1e-15) xyzw /= norm;
    sample.T_W_I.p = Eigen::Vector3d(values[0], values[1], values[2]);
    sample.T_W_I.q = Eigen::Quaterniond(xyzw[3], xyzw[0], xyzw[1], xyzw[2]);
    trajectory.push_back(sample);
    previous_line = source.line();
  }
  if (written_here && (end_line == 0 || bytes.back() != '\n')) {
    source.FailAtByte(bytes.size(), "the file ends without its end line '" +
                                        EndLine(trajectory.size()) +
                                        "' and a line break: it was cut short (a run stopped "
                                        "while writing?)");
  }
  if (trajectory.empty() && !written_here) {
    source.FailAtByte(bytes.size(), "the file holds no poses (only comments or blank lines)");
  }
  return trajectory;
}

}  // namespace io
}  // namespace autocal
