# Test sources of the slice module, relative to test/ (appended to DUPLEXFIT_MODULE_TESTS).
