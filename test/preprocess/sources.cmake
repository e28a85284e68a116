# Test sources of the preprocess module, relative to test/ (appended to DUPLEXFIT_MODULE_TESTS).
list(APPEND DUPLEXFIT_MODULE_TESTS
  preprocess/test_bilateral.cpp
  preprocess/test_normals.cpp
  preprocess/test_outliers.cpp
  preprocess/test_noise.cpp
  preprocess/test_preprocess_cli.cpp)
