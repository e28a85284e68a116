# Test sources of the render module, relative to test/ (appended to DUPLEXFIT_MODULE_TESTS).
