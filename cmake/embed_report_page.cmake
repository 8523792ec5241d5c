# Writes OUTPUT, a C++ source defining dhfcast::report_page_template(): TEMPLATE with the scripts
# it names inlined ("@THREE_JS@" by THREE_JS, "@ORBIT_CONTROLS_JS@" by ORBIT_CONTROLS_JS), as one
# raw string literal. Run as `cmake -DTEMPLATE=... -DTHREE_JS=... -DORBIT_CONTROLS_JS=...
# -DOUTPUT=... -P embed_report_page.cmake`.
cmake_minimum_required(VERSION 3.25)
file(READ "${TEMPLATE}" page)
file(READ "${THREE_JS}" three)
file(READ "${ORBIT_CONTROLS_JS}" controls)
string(REPLACE "@THREE_JS@" "${three}" page "${page}")
string(REPLACE "@ORBIT_CONTROLS_JS@" "${controls}" page "${page}")
set(delimiter "dhfcast_page")
string(FIND "${page}" ")${delimiter}\"" clash)
if(NOT clash EQUAL -1)
  message(FATAL_ERROR "${TEMPLATE}: the page holds the raw string's end \")${delimiter}\"")
endif()
file(WRITE "${OUTPUT}.tmp"
  "// Generated from ${TEMPLATE} by cmake/embed_report_page.cmake: do not edit.\n"
  "#include \"report_page.h\"\n\n"
  "namespace dhfcast {\n\n"
  "namespace {\n"
  "constexpr char kPage[] = R\"${delimiter}(${page})${delimiter}\";\n"
  "}  // namespace\n\n"
  "std::string_view report_page_template() { return {kPage, sizeof kPage - 1}; }\n\n"
  "}  // namespace dhfcast\n")
# Unchanged output keeps its time stamp: nothing recompiles.
file(COPY_FILE "${OUTPUT}.tmp" "${OUTPUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUTPUT}.tmp")
