# Sources of the render module, relative to lib/ (appended to DUPLEXFIT_MODULE_SOURCES).
list(APPEND DUPLEXFIT_MODULE_SOURCES render/section.cpp)
