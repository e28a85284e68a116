# Sources of the measure module, relative to lib/ (appended to DUPLEXFIT_MODULE_SOURCES).
list(APPEND DUPLEXFIT_MODULE_SOURCES measure/bvh.cpp measure/measure.cpp measure/check.cpp measure/quality.cpp)
