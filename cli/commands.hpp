// The duplexfit subcommands; each returns the process exit status and throws for errors (main maps
// exceptions to exit codes).
#pragma once

#include "args.hpp"

namespace duplexfit::cli {

int cmdDevices(int argc, char** argv);  // cmd_devices.cpp (CLI11: argv[0] is the command's name)
int cmdSolve(int argc, char** argv);    // cmd_solve.cpp
int cmdFit(int argc, char** argv);      // cmd_fit.cpp
int cmdMesh(int argc, char** argv);     // cmd_mesh.cpp
int cmdMeasure(Args& args);     // cmd_measure.cpp
int cmdCheck(Args& args);       // cmd_measure.cpp
int cmdSection(Args& args);     // cmd_section.cpp
int cmdSlice(Args& args);       // cmd_slice.cpp
int cmdDenoise(Args& args);     // cmd_preprocess.cpp
int cmdNormals(Args& args);     // cmd_preprocess.cpp

/// Options that take a value, per command (everything else is a flag).
extern const std::vector<std::string> kMeasureValued;
extern const std::vector<std::string> kCheckValued;
extern const std::vector<std::string> kSectionValued;
extern const std::vector<std::string> kSliceValued;
extern const std::vector<std::string> kDenoiseValued;
extern const std::vector<std::string> kNormalsValued;

/// Each module's part of `duplexfit --help` (indented like main.cpp's, ending in a newline).
extern const char* const kMeasureHelp;   // measure and check
extern const char* const kSectionHelp;
extern const char* const kSliceHelp;
extern const char* const kPreprocessHelp;  // denoise and normals

}  // namespace duplexfit::cli
