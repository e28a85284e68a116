// duplexfit command-line tool: the top-level help, the dispatch to the subcommands (cmd_*.cpp) and the
// mapping of exceptions to exit codes (1 usage, 2 I/O, 3 device, 4 numerical, 5 out of memory,
// 128 + N stopped by signal N).
#include <iostream>
#include <new>
#include <string>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/version.hpp"
#include "args.hpp"
#include "commands.hpp"
#include "options.hpp"
#include "signals.hpp"

namespace {

using namespace duplexfit;
using cli::UsageError;
using cli::kUsage;
using cli::kDevice;
using cli::kNumerical;

/// Every command with one line: what bare `duplexfit` prints, and the head of --help.
const char* kCommands = R"(usage: duplexfit <command> [options]

commands:
  fit INPUT          fit one field to an oriented cloud; write the surface, its offsets and the field
  mesh FIELD         extract one level set (or the printable shell) of a saved field
  slice FIELD        cut a saved field into print layers (CLI, SVG, PNG masks on the build plate)
  section FIELD      picture of f on a plane through the field, with its contours
  check MESH         closed, manifold, oriented, self-intersections, slivers of a mesh
  measure A B        Metro distance between two meshes, or an offset mesh's accuracy (--offset-of)
  denoise INPUT      bilateral point filter of an oriented cloud
  normals INPUT      estimate and orient the normals of a cloud
  solve              solve one duplex-fit level of a generated sphere (a solver check)
  devices            list every compute device

duplexfit COMMAND --help (or -h) lists the command's options, defaults and units;
duplexfit --help prints all of them; duplexfit --version the version.
)";

const std::vector<std::string> kCommandNames{"fit", "mesh", "slice", "section", "check", "measure",
                                             "denoise", "normals", "solve", "devices"};

const char* kHelp = R"(
reference:
  devices            list every compute device (spec, platform, name, type, memory, fp64, driver)
      --json           machine-readable output
  solve              assemble and solve the Wendland system of one duplex-fit level of a generated
                     sphere (surface, inward offset and off-surface points) with preconditioned CG
      --device SPEC    ref | P:D | cpu | gpu | name substring (default: $DUPLEXFIT_DEVICE, else first
                       GPU, else first CPU OpenCL device, else ref)
      --precision P    float (default) or double
      --points N       surface points on the sphere (default 20000; 3N unknowns)
      --delta D        inward offset distance, sphere radius 0.5 (default 0.05)
      --nnz K          target non-zeros per row, sets the support radius (default 45)
      --tol T          relative residual tolerance (default 1e-5 float, 1e-6 double)
      --max-iterations N  iteration cap (default 20000)
      --json           write the result as JSON on stdout
      --strict         exit with status 4 when CG does not converge
  fit INPUT          fit one field to an oriented cloud (PLY or XYZ "x y z nx ny nz"; normals outward)
                     or a triangle mesh (STL ascii/binary, OBJ, PLY with faces: sampled into a cloud with
                     face normals) and write zero.ply, offset1.ply, ..., field.dpxf and report.json
      --offset D[,D..] signed offsets in input units: positive = inward (hollowing), negative = outward
      --offset-rel     offsets are fractions of the bounding box's largest side
      -o DIR           output folder (default: current folder)
      --device SPEC, --precision float|double, --quiet, --strict (exit 4 if a level's CG fails,
                       the self-check below finds a component issue or a mesh written is not a closed
                       2-manifold free of self-intersections)
      --normals-inward the input normals point into the solid
      --validity-tol η offset validity tolerance (default 0.01)
      --levels M       number of levels (default: from the point density)
      --smoothing s    approximation mode, λ_k = s·k (default 0: interpolation; 0.2 when the cloud is filtered)
      --fit-tol ε      stop early when the residual at the next level's centres is below ε
      --tol T, --max-iterations N   CG tolerance and cap
      --cell H / --resolution R     marching grid cell size (default σ_M/2 within [side/512,
                                    side/128]) / cells along the longest side
      --max-triangles N / --max-error E  simplify every mesh to at most N triangles / within E input
                       units (meshoptimizer; a build without it says so); report.json gives each mesh's
                       deviation from its level set
      --no-clean       keep the raw marching-tetrahedra meshes (by default short edges are collapsed and
                       caps flipped: no triangle is degenerate once written in float32)
      --deviation-samples N  measure each mesh's deviation at N evenly strided vertices and face centres
                       (default 100000; 0: all of them), and for its max also those near the worst samples
      --evaluate-centres  evaluate every face centre in the projection's first round (by default most
                       are predicted from the vertices' tangent planes: 15-35% less projection time, the
                       same measured deviations; a predicted centre can miss detail smaller than a
                       triangle); --fast-projection, the old name of the default, is still accepted
      --format ply|obj|stl          mesh format (default ply)
      --drop-zero-normals           drop points whose normal is zero instead of keeping them at f = 0
      --side-test      also reject offset/off-surface points behind their nearest point's tangent
                       plane (removes spurious sheets from flipped normals; see FitOptions::sideTest)
      --no-crease-test keep offset/off-surface points that lie within half their step of a sample's
                       tangent plane across a convex sharp edge (by default rejected: an unsampled strip
                       along an edge hides that face from the validity test; see FitOptions::creaseTest)
      --no-anchors     no sign anchors in empty space (winding-number classified centres at levels
                       1 .. M - --anchor-skip, default 1; they stop holes filling with phantom solid)
      --no-overshoot-check  do not check the finest level at points D off the samples (D =
                       --overshoot-spacings, default 1.5 median spacings); by default those where f is less
                       than D/2 off the surface, with no sample nearer than D, join the level (bulbs and
                       bridges between sparse samples), in up to --overshoot-rounds (default 2) solves
      --no-medial      drop offset/off-surface points rejected by the validity test instead of moving
                       them onto the medial surface of thin parts with their true distance as target
      --offset-correction  add a correction level: points Newton-projected onto each δ level, fitted
                       to the distance to the samples with support min(σ_M, |δ|/2) (experimental, off)
      --estimate-normals  the cloud has no (trusted) normals: estimate them by PCA over --normals-k K
                       neighbours (default 15) and orient them outward (as `duplexfit normals`)
      --remove-outliers  drop far outliers before fitting (they are always reported in report.json
                       and named in a warning: points beyond the bulk's box by half its size)
      --denoise        bilateral point filter before fitting (as `duplexfit denoise`); override its
                       rules with --denoise-sigma-s, --denoise-sigma-r, --denoise-radius (input units),
                       --denoise-iterations N; the fit then defaults to --smoothing 0.2 (paper, Fig. 9).
                       Without it a cloud that looks noisy (scatter off its local planes above 0.4 point
                       spacings, report.json preprocessing.noise) is filtered and fitted so all the same
      --no-denoise     interpolate a noisy-looking cloud as it is (a hint on the log instead)
      --separate       baseline: fit the surface from the cloud alone and each offset surface from its
                       own offset points alone (one field each: field.dpxf, field_offsetN.dpxf)
      --min-component F  drop mesh components smaller than F of their mesh's area (default 0: none)
      --min-offset-component F  the same for the offset meshes only (default 0.001)
      --shell          also shell.ply (--format): the printable hollow part, the zero level plus the
                       smallest inward offset turned to face the cavity, as one closed mesh; report.json's
                       "shell" gives its volume, validity and whether the two surfaces intersect
      --drain-hole X,Y,Z,R  (repeatable; implies --shell) cut a vertical hole of radius R from the point
                       (in the cavity) straight down through the wall, cut in the field (docs/method.md);
                       --drain-hole auto[,R]: one at the lowest point of each cavity (R default: delta)
      --sample-points N / --sample-spacing H  samples of a mesh input: N in all, or a mean spacing H
                       (default: H = largest bounding-box side / 150, 1,000 to 2,000,000 samples)
      --mesh-reorient  orient an inconsistently oriented mesh's faces consistently (else an error);
                       an open or non-manifold mesh is a warning (--strict: an error)
      --input-type auto|cloud|mesh  what INPUT holds (auto: .stl, .obj and .ply with faces are meshes)
      --max-memory SIZE  memory budget (8G, 512M, 1.5GiB, bytes; default $DUPLEXFIT_MAX_MEMORY, else 75% of
                       the machine's memory): the grid, each level's system, the samples are estimated
                       before they are allocated and a run over the budget is refused (status 1, nothing
                       written). Also on mesh, section, slice, measure, check, denoise and normals
                     Every fit checks its meshes: zero-level components that carry no input point and
                     offset components not at about |D| from the zero level are warnings, listed under
                     "self_check" in report.json; --strict then exits with status 4.
  mesh FIELD         extract one level set of a saved field: --iso V (default 0) -o OUT.ply|obj|stl
                     [--device SPEC] [--cell H | --resolution R] [--min-component F]
                     --shell --iso D (D > 0): the printable shell between the levels 0 and D instead,
                     with --drain-hole X,Y,Z,R | auto[,R] as fit's
                     [--max-triangles N] [--max-error E] [--no-clean] [--deviation-samples N]
                     [--evaluate-centres] [--max-memory SIZE]
)";
const char* kHelpTail = R"(  --version, --help

Progress goes to stderr; --quiet silences it.
)";


}  // namespace

int main(int argc, char** argv) {
  try {
    if (argc < 2) {
      std::cerr << kCommands;
      return kUsage;
    }
    const std::string cmd = argv[1];
    if (cmd == "--help" || cmd == "-h" || cmd == "help") {
      std::cout << kCommands << kHelp << cli::kMeasureHelp << cli::kSectionHelp << cli::kSliceHelp
                << cli::kPreprocessHelp << kHelpTail;
      return 0;
    }
    if (cmd == "--version" || cmd == "-V") {
      std::cout << "duplexfit " << DUPLEXFIT_VERSION_STRING << "\n";
      return 0;
    }
    // The commands that write output sets stop cleanly on SIGINT/SIGTERM/SIGHUP (signals.hpp); the others
    // (devices, solve, measure, check) write nothing partial and keep the default actions.
    if (cmd == "fit" || cmd == "mesh" || cmd == "section" || cmd == "slice" || cmd == "denoise" || cmd == "normals") {
      cli::installStopSignals();
    }
    // Commands parsed with CLI11 see their own name as argv[0].
    if (cmd == "devices") return cli::cmdDevices(argc - 1, argv + 1);
    if (cmd == "solve") return cli::cmdSolve(argc - 1, argv + 1);
    if (cmd == "fit") return cli::cmdFit(argc - 1, argv + 1);
    if (cmd == "mesh") return cli::cmdMesh(argc - 1, argv + 1);
    if (cmd == "measure") return cli::cmdMeasure(argc - 1, argv + 1);
    if (cmd == "check") return cli::cmdCheck(argc - 1, argv + 1);
    if (cmd == "section") return cli::cmdSection(argc - 1, argv + 1);
    if (cmd == "slice") return cli::cmdSlice(argc - 1, argv + 1);
    if (cmd == "denoise") return cli::cmdDenoise(argc - 1, argv + 1);
    if (cmd == "normals") return cli::cmdNormals(argc - 1, argv + 1);
    const std::string near = cli::nearestWord(cmd, kCommandNames);
    throw UsageError("unknown command '" + cmd + "'" + (near.empty() ? "" : " (did you mean " + near + "?)") +
                     "; duplexfit with no arguments lists the commands");
  } catch (const UsageError& e) {
    std::cerr << "duplexfit: " << e.what() << "\n";
    return kUsage;
  } catch (const InvalidArgument& e) {
    std::cerr << "duplexfit: " << e.what() << "\n";
    return kUsage;
  } catch (const IoError& e) {
    std::cerr << "duplexfit: " << e.what() << "\n";
    return cli::kIo;
  } catch (const Cancelled& e) {
    if (const int signal = cli::stopSignal()) {
      std::cerr << "duplexfit: stopped by " << cli::stopSignalName(signal) << " (" << e.what()
                << "); nothing was written\n";
      return 128 + signal;
    }
    std::cerr << "duplexfit: " << e.what() << "\n";
    return kNumerical;
  } catch (const DeviceError& e) {
    std::cerr << "duplexfit: " << e.what() << "\n";
    return kDevice;
  } catch (const std::bad_alloc&) {
    // Its own status: not a numerical failure. The stage is the last one the command announced.
    std::cerr << "duplexfit: out of memory" << (cli::lastStage().empty() ? "" : " during " + cli::lastStage())
              << "; try a coarser grid, fewer points or a machine with more memory\n";
    return cli::kOutOfMemory;
  } catch (const std::exception& e) {
    std::cerr << "duplexfit: " << e.what() << "\n";
    return kNumerical;
  }
}
