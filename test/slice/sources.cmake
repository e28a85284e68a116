# Test sources of the slice module, relative to test/ (appended to DUPLEXFIT_MODULE_TESTS).
list(APPEND DUPLEXFIT_MODULE_TESTS slice/test_slice.cpp)
list(APPEND DUPLEXFIT_MODULE_TESTS slice/test_slice_io.cpp)
list(APPEND DUPLEXFIT_MODULE_TESTS slice/test_slice_plate.cpp)
list(APPEND DUPLEXFIT_MODULE_TESTS slice/test_slice_sl1.cpp)
