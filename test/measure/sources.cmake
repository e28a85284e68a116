# Test sources of the measure module, relative to test/ (appended to DUPLEXFIT_MODULE_TESTS).
list(APPEND DUPLEXFIT_MODULE_TESTS measure/test_measure.cpp measure/test_check.cpp measure/test_measure_cli.cpp
  measure/test_reliability.cpp)
