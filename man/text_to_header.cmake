# cmake -DTOOL=name -DHELP=help.txt -DUSAGE=usage.txt -DOUT=header.hpp -P text_to_header.cmake
# Wraps the two texts in C++ raw string literals, so that no character needs escaping.
if(NOT TOOL)
  set(TOOL qtmcell)
endif()
set(delimiter "${TOOL}_pod")
string(LENGTH "${delimiter}" length)
if(length GREATER 16)  # the C++ limit on a raw string delimiter
  set(delimiter "qtmv_pod")
endif()
file(READ "${HELP}" help)
file(READ "${USAGE}" usage)
string(REGEX REPLACE "\n\n+" "\n" usage "${usage}")  # pod2usage leaves a blank line between forms
foreach(text help usage)
  string(FIND "${${text}}" ")${delimiter}\"" at)
  if(NOT at EQUAL -1)
    message(FATAL_ERROR "${text} text contains the raw string delimiter )${delimiter}\"")
  endif()
endforeach()
file(WRITE "${OUT}"
"// Generated from man/${TOOL}.pod by man/CMakeLists.txt: edit the POD, not this file.
#pragma once

namespace qtmv::${TOOL} {

/// The whole manual as plain text (pod2text), printed by --help.
inline constexpr const char kHelpText[] = R\"${delimiter}(${help})${delimiter}\";

/// The SYNOPSIS alone (pod2usage -verbose 0), printed after a usage error.
inline constexpr const char kUsageText[] = R\"${delimiter}(${usage})${delimiter}\";

}  // namespace qtmv::${TOOL}
")
