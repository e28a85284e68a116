# Test sources of the measure module, relative to test/ (appended to DUPLEXFIT_MODULE_TESTS).
