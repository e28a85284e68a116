# Sources of the field module, relative to lib/ (appended to DUPLEXFIT_MODULE_SOURCES): the fitted
# function as a value type and file (field.cpp), its device evaluator with per-level uniform grids
# (field_evaluator.cpp), and the Wendland basis with its level matrix (wendland.cpp; on an OpenCL device
# assemble_device.cpp with kernels/assemble.cl). Depends on core, device, linalg storage, spatial and io
# only; fit, polygonize, slice, render and surfaces build on it.
list(APPEND DUPLEXFIT_MODULE_SOURCES field/wendland.cpp field/assemble_device.cpp field/field.cpp field/field_evaluator.cpp)
