// The duplexfit subcommands; each returns the process exit status and throws for errors (main maps
// exceptions to exit codes).
#pragma once

#include "args.hpp"

namespace duplexfit::cli {

int cmdDevices(int argc, char** argv);  // cmd_devices.cpp (CLI11: argv[0] is the command's name)
int cmdSolve(int argc, char** argv);    // cmd_solve.cpp
int cmdFit(int argc, char** argv);      // cmd_fit.cpp
int cmdMesh(int argc, char** argv);     // cmd_mesh.cpp
int cmdMeasure(int argc, char** argv);  // cmd_measure.cpp
int cmdCheck(int argc, char** argv);    // cmd_measure.cpp
int cmdSection(int argc, char** argv);  // cmd_section.cpp
int cmdSlice(int argc, char** argv);    // cmd_slice.cpp
int cmdDenoise(int argc, char** argv);  // cmd_preprocess.cpp
int cmdNormals(int argc, char** argv);  // cmd_preprocess.cpp

/// Each module's part of `duplexfit --help` (indented like main.cpp's, ending in a newline).
extern const char* const kMeasureHelp;   // measure and check
extern const char* const kSectionHelp;
extern const char* const kSliceHelp;
extern const char* const kPreprocessHelp;  // denoise and normals

}  // namespace duplexfit::cli
