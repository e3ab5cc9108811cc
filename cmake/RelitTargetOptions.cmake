# relit_target_options(<target>): the warning and sanitizer flags of relit's own targets.
# Target-scoped, so that a parent project embedding relit keeps its own flags.
#   RELIT_SANITIZE       AddressSanitizer + UBSan (gcc or clang); any UB report aborts the program.
#   RELIT_BUILD_FUZZERS  the same, plus libFuzzer's coverage instrumentation (clang only; tests/fuzz).
function(relit_target_options target)
  target_compile_options(${target} PRIVATE
    $<$<CXX_COMPILER_ID:GNU,Clang>:-Wall -Wextra -Wpedantic -Wno-missing-field-initializers>)
  if(RELIT_SANITIZE OR RELIT_BUILD_FUZZERS)
    set(_san -fsanitize=address,undefined)
    if(RELIT_BUILD_FUZZERS)
      list(APPEND _san -fsanitize=fuzzer-no-link)
    endif()
    target_compile_options(${target} PRIVATE ${_san} -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
    target_link_options(${target} PRIVATE -fsanitize=address,undefined)
  endif()
endfunction()
