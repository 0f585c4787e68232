#pragma once

// Number and text formatting shared by the reports and messages.

#include <cstdio>
#include <string>

namespace autocal {

// `value` with exactly `decimals` digits after the point ("%.*f").
inline std::string FormatFixed(double value, int decimals) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, value);
  return buffer;
}

// `value` in at most six significant digits ("%g"), for a message.
inline std::string FormatShort(double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%g", value);
  return buffer;
}

// `text` with the characters HTML and XML give a meaning (< > & ' ") as entities, for a
// report or a drawing that shows text from a run or an input file.
inline std::string EscapeXml(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

}  // namespace autocal
