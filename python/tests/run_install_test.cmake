# ctest driver: install the build into a scratch prefix, then import duplexfit from the prefix's package
# folder (PYTHONPATH=PREFIX/PACKAGE_DIR) and check that it is that copy that loads and works.
# Arguments: BUILD_DIR, PREFIX, PYTHON, PACKAGE_DIR.
file(REMOVE_RECURSE ${PREFIX})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${PREFIX}
  RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cmake --install failed (${rc}): ${err}")
endif()
set(site ${PREFIX}/${PACKAGE_DIR})
if(NOT EXISTS ${site}/duplexfit/__init__.py)
  message(FATAL_ERROR "the package was not installed into ${site}/duplexfit")
endif()
set(check [=[
import os, sys
import duplexfit
here = os.path.realpath(os.path.dirname(duplexfit.__file__))
want = os.path.realpath(os.path.join(sys.argv[1], "duplexfit"))
assert here == want, f"imported {here}, not the installed {want}"
assert os.path.realpath(os.path.dirname(duplexfit._native.__file__)) == want
ref = duplexfit.Device("ref")  # opens without OpenCL
print("installed duplexfit", duplexfit.__version__, "from", here, "device", ref.spec)
]=])
# From the prefix: `python -c` puts the working folder first on sys.path, and ctest's (build/python) holds the
# package as built.
execute_process(COMMAND ${CMAKE_COMMAND} -E env PYTHONPATH=${site} ${PYTHON} -c "${check}" ${site}
  WORKING_DIRECTORY ${PREFIX} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
message("${out}${err}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "importing the installed package failed (${rc})")
endif()
