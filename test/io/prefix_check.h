#pragma once

// Whether a reader refuses a file cut short: proper prefixes of a written file are written to
// `cut_path` and read with `read`, which must throw a ParseError naming that file.

#include <gtest/gtest.h>

#include <cstddef>
#include <fstream>
#include <iostream>
#include <set>
#include <string>

#include "autocal/common/error.h"

namespace autocal {
namespace io {
namespace test_data {

// Prefix lengths to try: every one near the start and the end, every line end (a cut at a
// line break is the one a line-based reader cannot see), and every `stride`-th in between
// (stride 1: all of them).
inline std::set<size_t> PrefixLengths(const std::string& bytes, size_t stride) {
  std::set<size_t> lengths;
  for (size_t n = 0; n < bytes.size(); ++n) {
    const bool edge = n < 200 || n + 200 > bytes.size();
    const bool line_end = n > 0 && bytes[n - 1] == '\n';
    if (edge || line_end || n % stride == 0) lengths.insert(n);
  }
  return lengths;
}

// Returns how many of the prefixes were accepted (each one is also a test failure) and prints
// it.
template <typename Read>
size_t CountAcceptedPrefixes(const std::string& bytes, const std::string& cut_path, Read read,
                             size_t stride = 1) {
  const std::set<size_t> lengths = PrefixLengths(bytes, stride);
  size_t accepted = 0;
  for (size_t n : lengths) {
    std::ofstream(cut_path, std::ios::binary | std::ios::trunc) << bytes.substr(0, n);
    try {
      read(cut_path);
      ++accepted;
      ADD_FAILURE() << "the first " << n << " of " << bytes.size() << " bytes were accepted";
    } catch (const ParseError& e) {
      EXPECT_EQ(e.location().file, cut_path);
    }
  }
  std::cout << cut_path << ": " << accepted << " of " << lengths.size() << " prefixes (of "
            << bytes.size() << " bytes) accepted\n";
  return accepted;
}

}  // namespace test_data
}  // namespace io
}  // namespace autocal
