# Writes a C++ header that holds the text of a file as a raw string literal, so that a library needs
# no data file at run time. Run at build time by rules/CMakeLists.txt (cmake -P), which makes the
# header depend on the input: editing the input regenerates the header and rebuilds its users.
#
#   cmake -DINPUT=<file> -DOUTPUT=<header> -DVARIABLE=<C++ name> -DNAMESPACE=<C++ namespace> -P embed_text.cmake
#
# The header defines `inline constexpr std::string_view VARIABLE` in NAMESPACE. The input must not
# contain the raw string's closing delimiter )wm_embed" (checked).
foreach(required INPUT OUTPUT VARIABLE NAMESPACE)
  if(NOT DEFINED ${required})
    message(FATAL_ERROR "embed_text.cmake: -D${required}=... is missing")
  endif()
endforeach()

file(READ "${INPUT}" text)
set(delimiter "wm_embed")
string(FIND "${text}" ")${delimiter}\"" clash)
if(NOT clash EQUAL -1)
  message(FATAL_ERROR "embed_text.cmake: ${INPUT} contains )${delimiter}\" and cannot be embedded as a raw string")
endif()

get_filename_component(input_name "${INPUT}" NAME)
set(header "#pragma once\n\n// Generated at build time from ${input_name} by rules/internal/embed_text.cmake; do not edit.\n\n#include <string_view>\n\nnamespace ${NAMESPACE} {\n\ninline constexpr std::string_view ${VARIABLE} = R\"${delimiter}(${text})${delimiter}\";\n\n}  // namespace ${NAMESPACE}\n")

# Rewrite only on change, so that an unchanged text does not rebuild the library.
set(existing "")
if(EXISTS "${OUTPUT}")
  file(READ "${OUTPUT}" existing)
endif()
if(NOT existing STREQUAL header)
  file(WRITE "${OUTPUT}" "${header}")
endif()
