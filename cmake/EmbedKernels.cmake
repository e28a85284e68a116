# duplexfit_embed_kernels(OUTPUT <cpp> FILES <cl>...): generate a .cpp holding every kernel source as a
# hex char array plus a name -> source table (lib/device/kernel_sources.hpp). Regenerated when a .cl changes.
function(duplexfit_embed_kernels)
  cmake_parse_arguments(ARG "" "OUTPUT" "FILES" ${ARGN})
  add_custom_command(
    OUTPUT ${ARG_OUTPUT}
    COMMAND ${CMAKE_COMMAND} -DOUTPUT=${ARG_OUTPUT} "-DFILES=${ARG_FILES}"
            -P ${PROJECT_SOURCE_DIR}/cmake/EmbedKernelsScript.cmake
    DEPENDS ${ARG_FILES} ${PROJECT_SOURCE_DIR}/cmake/EmbedKernelsScript.cmake
    COMMENT "Embedding OpenCL kernels"
    VERBATIM)
endfunction()
