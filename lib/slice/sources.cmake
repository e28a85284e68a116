# Sources of the slice module, relative to lib/ (appended to DUPLEXFIT_MODULE_SOURCES).
