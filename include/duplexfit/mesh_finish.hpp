// What the pipelines do with a level set's mesh after extraction (docs/method.md §7): cleaning (edge
// collapses of short edges and edge flips of caps, keeping the mesh 2-manifold and watertight, so that no
// triangle is degenerate once written in float32), optional simplification to a triangle budget or an
// error bound (meshoptimizer, when the build has it), and the mesh's deviation from the field's level set.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "duplexfit/field.hpp"
#include "duplexfit/interrupter.hpp"
#include "duplexfit/mesh.hpp"
#include "duplexfit/resources.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit {

// ---------------------------------------------------------------------------------------------
// Cleaning

struct CleanOptions {
  /// Edges shorter than this (input units) are collapsed; 0: only edges whose ends coincide in float32.
  double collapseLength = 0.0;
  /// Flip the longest edge of a cap (a triangle with an angle above capAngle degrees) when the flip raises
  /// the smallest angle of the two triangles and the quad is nearly flat (normals within flipNormalAngle).
  bool flips = true;
  double capAngle = 150.0;
  double flipNormalAngle = 20.0;
  /// A collapse is refused when a surviving triangle's normal would turn by more than this many degrees.
  double maxNormalChange = 60.0;
};

struct CleanReport {
  std::size_t verticesBefore = 0, facesBefore = 0, verticesAfter = 0, facesAfter = 0;
  std::size_t collapses = 0;        ///< edges collapsed
  std::size_t refusedTopology = 0;  ///< collapses refused: the mesh would stop being a closed 2-manifold there
  std::size_t refusedGeometry = 0;  ///< collapses refused: a triangle would flip, turn too far or degenerate
  /// Collapses refused because a surviving triangle would touch or cross one around it (tested where the
  /// triangles turn more than 60 degrees from the local normal: creases, tips, thin fins).
  std::size_t refusedCrossing = 0;
  std::size_t flips = 0;            ///< cap edges flipped
  /// Flips refused because a new triangle would touch or cross another (each other, or one around them).
  std::size_t refusedFlips = 0;
  std::size_t lockedVertices = 0;   ///< on a boundary or non-manifold edge or vertex: never moved
  std::size_t float32DegenerateBefore = 0, float32DegenerateAfter = 0;
  std::size_t sliversBefore = 0, sliversAfter = 0;  ///< minimum angle below 1°
  double minAngleBefore = 0.0, minAngleAfter = 0.0;  ///< degrees (TriangleQuality::minAngle)
  double shortestEdgeBefore = 0.0, shortestEdgeAfter = 0.0;
  double seconds = 0.0;
};

struct CleanResult {
  Mesh mesh;
  CleanReport report;
};

/// Collapses every edge shorter than options.collapseLength or with ends that coincide in float32
/// (shortest first; the new vertex at the midpoint, else at either end), then flips cap edges, then
/// collapses the shortest edge of any triangle still degenerate in float32. A collapse is made only when
/// it keeps the mesh 2-manifold (the edge has two triangles, the ends share exactly the two opposite
/// vertices, no two triangles become one) and no surviving triangle flips, turns by more than
/// maxNormalChange or becomes float32-degenerate; vertices on a boundary or non-manifold edge or at a
/// non-manifold vertex are never moved. A watertight, manifold, oriented mesh stays so, with the same
/// components and Euler characteristic. Deterministic. @throws InvalidArgument for bad indices/options.
CleanResult cleanMesh(const Mesh& mesh, const CleanOptions& options = {});

// ---------------------------------------------------------------------------------------------
// Simplification (meshoptimizer)

/// Whether this build has meshoptimizer (simplifyMesh works).
bool simplificationAvailable() noexcept;

struct SimplifyOptions {
  /// Triangle budget (0: none).
  std::size_t maxTriangles = 0;
  /// Error bound in input units (0: none): meshopt_simplify's target error, which it takes relative to the
  /// mesh extent (meshopt_simplifyScale). With both set the simplifier stops at whichever comes first.
  double maxError = 0.0;
};

struct SimplifyReport {
  bool applied = false;  ///< a budget or bound was set
  std::size_t facesBefore = 0, facesAfter = 0;
  double targetError = 0.0;  ///< relative to the extent, as passed to meshopt_simplify (1: no bound)
  double resultError = 0.0;  ///< meshoptimizer's own estimate, input units (0 after the fallback)
  /// Pairs of triangles on the same three vertices that meshopt_simplify left (a collapsed tetrahedron),
  /// removed before the topology check.
  std::size_t duplicatePairsRemoved = 0;
  /// meshoptimizer's result still had another topology than the input (it does not check the link
  /// condition: two sheets can end up sharing an edge), so the mesh was simplified instead by the
  /// library's own quadric-error edge collapses, which keep a closed 2-manifold one.
  bool fallback = false;
  /// The result has the input's topology (watertight, manifold and oriented as the input, same components
  /// and Euler characteristic). false only if the fallback failed too: the input is returned unchanged.
  bool topologyKept = true;
  double seconds = 0.0;
};

struct SimplifyResult {
  Mesh mesh;
  SimplifyReport report;
};

/// meshopt_simplify (the topology-preserving simplifier, never the sloppy one) to the budget and/or bound;
/// unreferenced vertices and duplicate triangle pairs are removed, and the result's topology is checked
/// against the input's. When it differs, the library's own quadric-error edge collapses (link condition
/// and normal checks, as cleanMesh) simplify the input instead (SimplifyReport::fallback). No budget and no
/// bound: the mesh as it is. @throws InvalidArgument when a budget or bound is set and the build lacks
/// meshoptimizer (the message says so), or for a negative bound.
SimplifyResult simplifyMesh(const Mesh& mesh, const SimplifyOptions& options);

// ---------------------------------------------------------------------------------------------
// Deviation from the level set

/// Values (and gradients, #Q×3) of a field at #Q points.
using FieldGradientSampler = std::function<void(const Points& queries, Eigen::VectorXd& values, Points& gradients)>;

/// How far a mesh of {f = iso} is from it, at every vertex and every face centre: the first-order
/// distance |f(x) − iso| / |∇f(x)|, and where that exceeds a quarter of `limit`, the length of the Newton
/// path x ← x − (f(x) − iso) ∇f/|∇f|² onto the level set (10 steps of at most 1% of the side each; kept
/// when it converges: |f − iso| ≤ 1e-6·side or a first-order rest ≤ 1e-5·side), which stays accurate
/// where |∇f| is small and the first-order estimate overshoots (a flat maximum of f just above iso in a
/// thin part).
struct LevelSetDeviation {
  std::size_t candidates = 0;      ///< vertices + faces of the mesh
  std::size_t samples = 0;         ///< the samples measured (all candidates, or an even stride of them)
  std::size_t flatSamples = 0;     ///< samples with |∇f| < 1e-6, left out
  std::size_t refinedSamples = 0;  ///< samples (local ones too) whose Newton path replaced the first-order estimate
  /// With a stride: the vertices and face centres measured around the samples beyond a quarter of the
  /// limit (within 4 rings, at most maxSamples), for max and maxAt only; 0 when every candidate is measured.
  std::size_t localSamples = 0;
  /// max and maxAt: over the samples and the local samples; mean, rms, the percentiles and aboveLimit: over
  /// the samples (an even stride, or every candidate).
  double max = 0.0, mean = 0.0, rms = 0.0;
  double p99 = 0.0, p999 = 0.0;  ///< 99th and 99.9th percentiles (nearest rank)
  Eigen::Vector3d maxAt = Eigen::Vector3d::Zero();
  double side = 0.0;         ///< the reference length: the largest side of the field's input bounds
  double relativeMax = 0.0;  ///< max / side
  double limit = 0.0;        ///< 0.001 · side, the target of docs/method.md §7
  std::size_t aboveLimit = 0;  ///< samples farther than limit
  /// Where the measured points (samples and local samples) lie farther than limit, at most kAboveLimitAt of
  /// them (the pipelines' neck pass refines the grid cells there).
  std::vector<Eigen::Vector3d> aboveLimitAt;
  /// The same for the points farther than half the limit (the extent of a neck around its worst points).
  std::vector<Eigen::Vector3d> nearLimitAt;
  static constexpr std::size_t kAboveLimitAt = 4096;
  double seconds = 0.0;
};

/// First-order distances |f − iso| / |∇f| (−1 where |∇f| < 1e-6) already evaluated at a mesh's vertices
/// and face centres (the centre (a + b + c) / 3 of its corners in face order), NaN where not known: what
/// projectToLevelSet evaluated last at the positions it leaves. The sampler's value at a point does not
/// depend on the rest of its batch, so these are the values an evaluation there would give.
struct KnownFirstOrder {
  std::vector<double> vertices;  ///< one a vertex (or empty: none known)
  std::vector<double> centres;   ///< one a face (or empty: none known)
};

/// maxSamples > 0 measures an even stride of at most that many of the vertices and face centres, then, for
/// the max, every candidate near the stride's samples beyond a quarter of the limit (localSamples).
/// `known` (optional): first-order values taken instead of evaluating (the same measure, fewer evaluations).
LevelSetDeviation levelSetDeviation(const FieldGradientSampler& sampler, const Mesh& mesh, double iso, double side,
                                    std::size_t maxSamples = 0, const KnownFirstOrder* known = nullptr);
/// The same through a field's evaluator; side = the largest side of field.bounds().
LevelSetDeviation levelSetDeviation(const FieldEvaluator& evaluator, const ImplicitField& field, const Mesh& mesh,
                                    double iso, std::size_t maxSamples = 0, const KnownFirstOrder* known = nullptr);

// ---------------------------------------------------------------------------------------------
// Moving the mesh onto its level set

struct ProjectOptions {
  /// Faces whose centre is farther than this from the level set (input units; the length of its Newton
  /// path onto it) have their longest edge split, the new vertex projected in turn. 0: vertices are
  /// projected, no face is split.
  double target = 0.0;
  /// Split rounds at most (each round splits at most one edge per marked face, then projects the new
  /// vertices and measures the faces they touch).
  int rounds = 8;
  /// The splits stop once the mesh has this many times its input's faces (or maxFaces, when set).
  double maxGrowth = 1.25;
  std::size_t maxFaces = 0;
  /// A vertex is not moved farther than this (input units; 0: no cap): the extraction's vertices lie on
  /// grid edges that cross the level set, so a longer path has left for another sheet.
  double maxMove = 0.0;
  /// A move is refused when a triangle around the vertex would turn by more than this many degrees from
  /// its extracted normal, become float32-degenerate, or get a smallest angle below minAngle degrees
  /// (unless it was already smaller).
  double maxNormalChange = 80.0;
  double minAngle = 1.0;
  /// In the first split round, predict the centre of each face whose three vertices are on the level set
  /// (with ∇f known there) from the corners' tangent planes, and evaluate only the faces whose prediction
  /// is beyond a quarter of the target (docs/method.md §7). Faster, but blind to detail smaller than a
  /// triangle: on fandisk_50k 8 of 224k predicted faces were in fact beyond the target (at most 1.75×
  /// it). Off: every face centre is evaluated.
  bool estimateCentres = false;
  /// Afterwards, check the faces the moves changed for intersecting and float32-degenerate triangles
  /// (checkMesh's tests) and move the vertices around them back to the extracted surface until there are
  /// none (at most 12 rounds, the last one moves every vertex back).
  bool undoSelfIntersections = true;
  /// An open mesh: the ends of its boundary edges are not moved (nor are boundary edges ever split), so
  /// that it still fits the mesh around it (the neck pass's patch, docs/method.md §7).
  bool keepBoundary = false;
  /// The budget of that check.
  ResourceLimits limits{};
};

struct ProjectReport {
  bool applied = false;
  std::size_t verticesBefore = 0, facesBefore = 0, verticesAfter = 0, facesAfter = 0;
  std::size_t moved = 0;         ///< vertices moved onto the level set (extracted and new ones)
  std::size_t partial = 0;       ///< of the moved ones, moved half or a quarter of the way (the whole way was refused)
  std::size_t refused = 0;       ///< moves refused by the normal, angle or float32 checks
  std::size_t notConverged = 0;  ///< Newton paths that did not reach the level set (or ran past maxMove)
  std::size_t splits = 0;        ///< edges split
  int rounds = 0;                ///< split rounds made
  std::size_t markedLeft = 0;    ///< faces still beyond the target when the splits stopped
  std::size_t centresEvaluated = 0;  ///< face centres evaluated (all rounds)
  std::size_t centresPredicted = 0;  ///< face centres predicted within the target instead (estimateCentres)
  /// Intersecting triangle pairs after the moves, before the undo, with a face the moves changed (pairs of
  /// unmoved faces cross on the extracted mesh itself: no undo changes them, and they are not counted).
  std::size_t selfIntersectionsFound = 0;
  std::size_t reverted = 0;      ///< vertices moved back to the extracted surface by the undo
  /// Whether the undo ran (undoSelfIntersections); selfIntersectionsLeft is then the number of intersecting
  /// pairs the result has with a face that moved or moved back (pairs of unmoved faces, which cross on the
  /// extracted surface itself, are not looked for).
  bool selfIntersectionsChecked = false;
  std::size_t selfIntersectionsLeft = 0;
  double seconds = 0.0;
};

struct ProjectResult {
  Mesh mesh;
  ProjectReport report;
  /// The first-order distances last evaluated at the result's vertices and face centres where they still
  /// stand (for levelSetDeviation; NaN elsewhere: moved part of the way, moved back, split).
  KnownFirstOrder known;
};

/// Moves every vertex of a mesh of {f = iso} onto the level set (Newton steps x ← x − (f − iso) ∇f/|∇f|²,
/// at most 1% of `side` each, as levelSetDeviation), refusing moves that would fold or degenerate a
/// triangle, then, while faces have their centre farther than options.target from the level set, splits
/// their longest edge at its midpoint (both triangles of the edge: the mesh stays conforming) and projects
/// the new vertex. Only edges with exactly two consistently oriented triangles are split, so a watertight,
/// manifold, oriented mesh stays so, with the same components and Euler characteristic. Deterministic.
/// @throws InvalidArgument for bad indices or options.
ProjectResult projectToLevelSet(const FieldGradientSampler& sampler, const Mesh& mesh, double iso, double side,
                                const ProjectOptions& options);

// ---------------------------------------------------------------------------------------------
// The pipelines' step

struct MeshFinishOptions {
  bool clean = true;
  /// Collapse edges shorter than this fraction of the grid cell (CleanOptions::collapseLength).
  double collapseFraction = 0.1;
  SimplifyOptions simplify{};
  /// Measure each mesh's deviation from its level set (one field evaluation with gradients per vertex and
  /// per face).
  bool measureDeviation = true;
  /// At most this many samples (an even stride over vertices and face centres) per mesh; 0: all. The mean
  /// and the quantiles of 100k samples are within a few per cent of the full measure; the maximum is the
  /// largest of the samples (report.json gives samples and candidates). Each sample costs one gradient
  /// evaluation (plus Newton steps when it is not small): on fandisk_50k all 386k + 248k samples took
  /// 7 s, longer than the grid sampling; on fandisk_550k's 3.5M-triangle zero mesh all 5.3M took 25 s.
  std::size_t deviationSamples = 100000;
  /// After cleaning and simplification, move the vertices onto the level set and split the faces whose
  /// centre is farther than projectTarget · side from it (projectToLevelSet; side = the largest side of
  /// the field's bounds). The splits stop at 1.25× the faces, or at the simplification's budget.
  bool project = true;
  double projectTarget = 5e-4;
  /// ProjectOptions::estimateCentres: most first-round face centres predicted from the vertices' tangent
  /// planes (on by default since 2026-12-04: every vertex and centre measured afterwards gave the same
  /// deviations on five models, docs/method.md §7; `--evaluate-centres` turns it off).
  bool predictCentres = true;
  /// Meshes finished at once, each on its own host thread (their field evaluations take turns on the
  /// device); 0: as many as the host has hardware threads, at most 4. Each mesh's result is the same as
  /// when they are finished one after another; the memory of the meshes in flight adds up.
  std::size_t concurrentMeshes = 0;
};

/// The pipelines' neck pass on one mesh (SurfaceOptions::neckPassMaxFaces).
struct NeckPassReport {
  bool applied = false;          ///< the level set was extracted and finished again
  bool kept = false;             ///< the new mesh replaced the first (closer to its level set, still closed)
  std::size_t cells = 0;         ///< grid cells refined one level more (or asked for, when too many)
  bool tooManyCells = false;     ///< not applied: more cells than SurfaceOptions::neckPassMaxCells
  std::size_t facesBefore = 0, facesAfter = 0;  ///< of the first mesh and of the new one
  double maxBefore = 0.0, maxAfter = 0.0;       ///< their deviation maxima, fractions of the side
  /// Kept by the local replacement: only the faces around the cells were replaced (by a patch extracted
  /// and finished there, joined by a band); false: the whole level set was extracted and finished again.
  bool local = false;
  std::size_t removedFaces = 0, patchFaces = 0;  ///< of the local replacement (patch and band, finished)
  std::string localRefused;  ///< why a local replacement was not kept (then the whole mesh was redone)
  double seconds = 0.0;
};

struct MeshFinishReport {
  CleanReport clean;        ///< zero when cleaning is off
  SimplifyReport simplify;  ///< applied false without a budget or bound
  ProjectReport project;    ///< applied false when projection is off
  bool deviationMeasured = false;
  LevelSetDeviation deviation;
  NeckPassReport neckPass;  ///< set by the pipelines (applied false otherwise)
  double seconds = 0.0;
};

/// @throws InvalidArgument for a negative fraction or bound, or a budget or bound without meshoptimizer in
/// the build ("... this build of duplexfit has no meshoptimizer ...").
void validateFinishOptions(const MeshFinishOptions& options);

struct FinishResult {
  std::vector<Mesh> meshes;
  std::vector<MeshFinishReport> reports;  ///< one per mesh
  double seconds = 0.0;
};

/// Cleans (collapse length = collapseFraction · cell), simplifies (when asked; then cleans again), projects
/// onto the level set (when asked; moves capped at 3 cells) and measures every mesh of {f = isoValues[i]} (meshes[i]) against `field` through `evaluator`.
/// @throws InvalidArgument (options, sizes), DeviceError, Cancelled (checked between meshes).
FinishResult finishSurfaces(const FieldEvaluator& evaluator, const ImplicitField& field, std::vector<Mesh> meshes,
                            const std::vector<double>& isoValues, double cell, const MeshFinishOptions& options = {},
                            Interrupter* interrupter = nullptr);

}  // namespace duplexfit
