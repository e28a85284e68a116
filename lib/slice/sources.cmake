# Sources of the slice module, relative to lib/ (appended to DUPLEXFIT_MODULE_SOURCES).
list(APPEND DUPLEXFIT_MODULE_SOURCES slice/slice.cpp slice/slice_io.cpp slice/placement.cpp
  slice/sl1.cpp)
