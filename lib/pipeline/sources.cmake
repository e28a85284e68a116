# Sources of the pipeline module, relative to lib/ (appended to DUPLEXFIT_MODULE_SOURCES).
list(APPEND DUPLEXFIT_MODULE_SOURCES pipeline/pipeline.cpp pipeline/report_json.cpp pipeline/jobs.cpp
  pipeline/jobs_json.cpp)
