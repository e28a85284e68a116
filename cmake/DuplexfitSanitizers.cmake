set(DUPLEXFIT_SANITIZER_DEFAULTS ${CMAKE_CURRENT_LIST_DIR}/sanitizer_defaults.cpp)

# duplexfit_set_sanitizers(target): DUPLEXFIT_SANITIZE="address;undefined" -> compile and link flags.
function(duplexfit_set_sanitizers target)
  if(DUPLEXFIT_SANITIZE)
    string(REPLACE ";" "," _list "${DUPLEXFIT_SANITIZE}")
    target_compile_options(${target} PRIVATE -fsanitize=${_list} -fno-omit-frame-pointer
                                             -fno-sanitize-recover=undefined)
    # A Debug build (-O0) gets -O1: the AddressSanitizer documentation recommends it "to get reasonable
    # performance". At -O0 the header templates we instantiate (Eigen) and the meshing loops ran the
    # sanitizer suite past CI's 90 minutes; -O1 keeps assertions, frames and every sanitizer check.
    target_compile_options(${target} PRIVATE $<$<CONFIG:Debug>:-O1>)
    target_link_options(${target} PRIVATE -fsanitize=${_list})
    get_target_property(_type ${target} TYPE)
    if(_type STREQUAL "EXECUTABLE")
      # Default runtime options every sanitized program starts with (see the file).
      target_sources(${target} PRIVATE ${DUPLEXFIT_SANITIZER_DEFAULTS})
    endif()
  endif()
endfunction()

# Our own targets get both warning and sanitizer settings.
function(duplexfit_configure_target target)
  duplexfit_set_warnings(${target})
  duplexfit_set_sanitizers(${target})
endfunction()
