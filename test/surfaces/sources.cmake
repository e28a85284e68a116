# Test sources of the surfaces module, relative to test/ (appended to DUPLEXFIT_MODULE_TESTS).
list(APPEND DUPLEXFIT_MODULE_TESTS surfaces/test_self_check.cpp surfaces/test_shell.cpp
  surfaces/test_mesh_finish.cpp surfaces/test_splice.cpp)
