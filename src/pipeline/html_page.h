#pragma once

// The frame every autocal HTML page shares: one self-contained document (inline CSS, no
// script, no external resource) with the title as its first heading.

#include <cctype>
#include <string>
#include <vector>

#include "autocal/common/format.h"

namespace autocal {
namespace pipeline {

inline std::string HtmlPageStart(const std::string& title) {
  return "<!DOCTYPE html><html><head><meta charset='utf-8'><title>" + EscapeXml(title) +
         "</title><style>body{font-family:sans-serif;max-width:1180px;margin:auto}"
         "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px;"
         "text-align:right}figure{display:inline-block;margin:8px}svg text{font-size:11px}"
         ".warn{color:#a40}</style></head><body><h1>" +
         EscapeXml(title) + "</h1>\n";
}

inline std::string HtmlPageEnd() { return "</body></html>\n"; }

// `text` as one segment of a link's path: every byte but the unreserved letters, digits and
// - . _ ~ percent-encoded (RFC 3986), so that a name with '#', '%', '?', '/' or a space links
// to the file of that name.
inline std::string PercentEncoded(const std::string& text) {
  static const char kHex[] = "0123456789ABCDEF";
  std::string out;
  for (const char c : text) {
    const unsigned char byte = static_cast<unsigned char>(c);
    if (std::isalnum(byte) != 0 || c == '-' || c == '.' || c == '_' || c == '~') {
      out += c;
    } else {
      out += '%';
      out += kHex[byte >> 4];
      out += kHex[byte & 15];
    }
  }
  return out;
}

// A list of warnings under a heading, or nothing when there are none.
inline std::string HtmlWarnings(const std::string& heading, const std::vector<std::string>& lines) {
  if (lines.empty()) return "";
  std::string html = "<h2>" + EscapeXml(heading) + "</h2><ul>";
  for (const std::string& line : lines) html += "<li class='warn'>" + EscapeXml(line) + "</li>";
  return html + "</ul>\n";
}

}  // namespace pipeline
}  // namespace autocal
