# Sources of the measure module, relative to lib/ (appended to DUPLEXFIT_MODULE_SOURCES).
