# Test sources of the render module, relative to test/ (appended to DUPLEXFIT_MODULE_TESTS).
list(APPEND DUPLEXFIT_MODULE_TESTS render/test_section.cpp)
