# Sources of the surfaces module, relative to lib/ (appended to DUPLEXFIT_MODULE_SOURCES).
list(APPEND DUPLEXFIT_MODULE_SOURCES surfaces/surfaces.cpp surfaces/self_check.cpp surfaces/shell.cpp
  surfaces/clean.cpp surfaces/simplify.cpp surfaces/finish.cpp surfaces/project.cpp
  surfaces/surfaces_distributed.cpp surfaces/splice.cpp)
