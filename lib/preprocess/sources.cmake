# Sources of the preprocess module, relative to lib/ (appended to DUPLEXFIT_MODULE_SOURCES).
list(APPEND DUPLEXFIT_MODULE_SOURCES
  preprocess/preprocess_device.cpp
  preprocess/bilateral.cpp
  preprocess/normals.cpp
  preprocess/outliers.cpp
  preprocess/noise.cpp)
