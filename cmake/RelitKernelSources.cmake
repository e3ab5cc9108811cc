# relit_embed_kernel_sources(<target> <dir>): compiles the OpenCL sources of <dir> (*.cl, *.clh) into
# <target>, which hands them to relit::add_kernel_source() when it starts (cmake/EmbedFiles.cmake, REGISTER).
# For the kernels of a test or benchmark program, which are no part of librelit; they may #include relit's
# headers ("common.clh"), and RELIT_KERNEL_DIR overrides them like relit's own.
function(relit_embed_kernel_sources target dir)
  file(GLOB _files CONFIGURE_DEPENDS "${dir}/*.cl" "${dir}/*.clh")
  set(_out "${CMAKE_CURRENT_BINARY_DIR}/generated/${target}_kernels.cpp")
  add_custom_command(
    OUTPUT "${_out}"
    COMMAND "${CMAKE_COMMAND}" -DDIR=${dir} "-DGLOBS=*.cl|*.clh" -DREGISTER=ON -DOUTPUT=${_out}
            -P "${PROJECT_SOURCE_DIR}/cmake/EmbedFiles.cmake"
    DEPENDS ${_files} "${PROJECT_SOURCE_DIR}/cmake/EmbedFiles.cmake"
    COMMENT "Embedding the kernels of ${dir} into ${target}"
    VERBATIM)
  target_sources(${target} PRIVATE "${_out}")
endfunction()
