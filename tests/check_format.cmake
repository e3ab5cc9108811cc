# Fails when a C++ or OpenCL source differs from what clang-format makes of it with the repository's
# .clang-format (run `clang-format -i --style=file FILE` to fix). -DCLANG_FORMAT=... -DSOURCE_DIR=...
if(NOT CLANG_FORMAT)
  message(FATAL_ERROR "clang-format was not found: scripts/setup.sh installs it (Debian package clang-format)")
endif()
set(_files)
foreach(_dir lib apps bindings tests bench kernels scripts docs/examples)
  file(GLOB_RECURSE _found "${SOURCE_DIR}/${_dir}/*.cpp" "${SOURCE_DIR}/${_dir}/*.hpp" "${SOURCE_DIR}/${_dir}/*.h"
       "${SOURCE_DIR}/${_dir}/*.cl" "${SOURCE_DIR}/${_dir}/*.clh")
  list(APPEND _files ${_found})
endforeach()
list(FILTER _files EXCLUDE REGEX "/tests/data/")
list(LENGTH _files _n)
execute_process(COMMAND "${CLANG_FORMAT}" --style=file --dry-run --Werror ${_files}
                WORKING_DIRECTORY "${SOURCE_DIR}" RESULT_VARIABLE _rc ERROR_VARIABLE _err)
if(NOT _rc EQUAL 0)
  message(FATAL_ERROR "${_err}\nnot formatted (above); clang-format -i --style=file FILE fixes it")
endif()
message(STATUS "${_n} files formatted")
