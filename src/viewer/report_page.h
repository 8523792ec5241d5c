// The page template of report.html, with three.js inlined, compiled into the program (its
// source is generated at build time from report_template.html by cmake/embed_report_page.cmake).
#pragma once

#include <string_view>

namespace dhfcast {

// The whole page; the data goes where "@DHFCAST_REPORT_DATA@" stands.
std::string_view report_page_template();

}  // namespace dhfcast
