# Sources of the preprocess module, relative to lib/ (appended to DUPLEXFIT_MODULE_SOURCES).
