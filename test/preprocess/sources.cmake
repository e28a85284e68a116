# Test sources of the preprocess module, relative to test/ (appended to DUPLEXFIT_MODULE_TESTS).
