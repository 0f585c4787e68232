#pragma once

// The frame every autocal HTML page shares: one self-contained document (inline CSS, no
// script, no external resource) with the title as its first heading.

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

// A list of warnings under a heading, or nothing when there are none.
inline std::string HtmlWarnings(const std::string& heading, const std::vector<std::string>& lines) {
  if (lines.empty()) return "";
  std::string html = "<h2>" + EscapeXml(heading) + "</h2><ul>";
  for (const std::string& line : lines) html += "<li class='warn'>" + EscapeXml(line) + "</li>";
  return html + "</ul>\n";
}

}  // namespace pipeline
}  // namespace autocal
