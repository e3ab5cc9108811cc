# Runs relit's kernel tests on Oclgrind, the OpenCL device simulator, and fails on any report it makes: data
# races (global and local memory), out-of-bounds accesses, barrier divergence, invalid API calls. The tests
# see an "Oclgrind Simulator" device and shrink their sizes (test::tiny_sizes()).
#   -DOCLGRIND=... -DTEST_BINARY=... -DFILTER=<gtest filter> -DLOG=<file> -DWORK_DIR=...
#   -DEXTRA="--uninitialized" adds Oclgrind options (docs/reliability.md: what its uninitialised-value check does
#   on relit's kernels).
if(NOT OCLGRIND)
  message(FATAL_ERROR "oclgrind was not found: scripts/setup.sh installs it (Debian package oclgrind)")
endif()
file(REMOVE "${LOG}")
separate_arguments(EXTRA)
file(MAKE_DIRECTORY "${WORK_DIR}")
execute_process(
  COMMAND "${OCLGRIND}" --data-races --check-api ${EXTRA} --max-errors 50 --log "${LOG}"
          "${TEST_BINARY}" "--gtest_filter=${FILTER}" --gtest_brief=1
  WORKING_DIRECTORY "${WORK_DIR}" RESULT_VARIABLE _rc OUTPUT_VARIABLE _out ERROR_VARIABLE _out)
set(_log "")
if(EXISTS "${LOG}")
  file(READ "${LOG}" _log)
endif()
string(REGEX MATCH "\\[==========\\] [0-9]+ tests? from [0-9]+ test suites? ran" _ran "${_out}")
message("${_out}")
if(NOT _rc EQUAL 0)
  message(FATAL_ERROR "the kernel tests failed on Oclgrind (exit ${_rc})\n${_log}")
endif()
if(NOT _ran)
  message(FATAL_ERROR "no test ran on Oclgrind (filter ${FILTER})")
endif()
string(STRIP "${_log}" _log)
if(NOT _log STREQUAL "")
  message(FATAL_ERROR "Oclgrind reported errors (log: ${LOG}):\n${_log}")
endif()
message(STATUS "Oclgrind: no report (${_ran})")
