// The printable hollow part (docs/method.md, "Printable shell and drain holes"): one closed shell mesh
// for a slicer, the outer surface (the zero level) and the inner one (an inward offset δ > 0) with its
// faces reversed so that its normals point into the cavity, with a report (watertight, 2-manifold,
// oriented, enclosed volume, intersections between the surfaces); and drain holes, cut in the field so
// that meshes and slices agree: the hollow solid is S = {g ≥ 0}, g = min(f, δ − f), the drained one
// {g' ≥ 0}, g' = min(g, c_1, …, c_n) with c_i the signed distance to hole i (> 0 outside it),
// polygonized as one closed mesh.
//
//     duplexfit::ShellOptions o;
//     o.offset = 0.02;
//     o.drainHoles.push_back({Eigen::Vector3d(0, 0, -0.3), 0.03});
//     const duplexfit::ShellResult shell = duplexfit::drainShell(sampler, grid, zero, offset, o);
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "duplexfit/field.hpp"
#include "duplexfit/interrupter.hpp"
#include "duplexfit/mesh.hpp"
#include "duplexfit/polygonize.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit {

/// A drain hole: the solid vertical cylinder of radius `radius` about the line x = point.x, y = point.y,
/// from the height point.z downward (−z) without end. `point` is meant to lie in the cavity: the hole then
/// runs from the cavity down through the bottom wall to the outside. Everything of the part below the
/// point inside the cylinder is removed (place a hole where the way down leaves the part through one wall).
struct DrainHole {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  ///< input units
  double radius = 0.0;                              ///< > 0, input units
};

/// c(x): the signed Euclidean distance from x to the hole's cylinder, > 0 outside, < 0 inside (minus the
/// distance to its boundary).
double drainHoleDistance(const DrainHole& hole, const Eigen::Vector3d& x);

/// g' = min(f, δ − f, c_1, …, c_n) at `queries` from the samples `f` of the field there (δ = offset > 0);
/// where `f` carries gradients (and Hessians), so does the result: those of the piece that attains the
/// minimum. @throws InvalidArgument when the sizes differ.
FieldSamples drainedShellSamples(const Points& queries, const FieldSamples& f, double offset,
                                 const std::vector<DrainHole>& holes);

/// One hole per cavity (each positively oriented component of the offset mesh, i.e. the boundary of a
/// region {f > δ}): on the vertical through its lowest vertex, its top min(radius, half the component's
/// height) above that vertex.
std::vector<DrainHole> autoDrainHoles(const Mesh& offsetMesh, double radius);

struct ShellOptions {
  /// δ > 0: the inner surface is the level {f = δ} (the zero mesh is {f = 0}).
  double offset = 0.0;
  /// Holes to cut (drainShell only).
  std::vector<DrainHole> drainHoles;
  /// Also one hole per cavity at its lowest point (autoDrainHoles), of radius autoDrainRadius (0: δ).
  bool autoDrainHoles = false;
  double autoDrainRadius = 0.0;
  /// drainShell: cavity components of the drained mesh (negative enclosed volume) whose area is below this
  /// fraction of the mesh's area are dropped (the pocket is filled), as the offset mesh's clean-up drops
  /// slivers of the δ level (PipelineOptions::selfCheck.minOffsetAreaFraction). In [0, 1).
  double minCavityFraction = 0.0;
  /// Look for intersecting triangle pairs in the shell mesh (checkMesh's self-intersection test): a shell
  /// whose inner surface crosses the outer one is not a valid solid.
  bool checkIntersections = true;
  /// checkMesh's work bound (CheckOptions::candidatePairBudget).
  std::size_t candidatePairBudget = 400'000'000;

  /// Holes are cut: drainHoles given or autoDrainHoles.
  bool drained() const noexcept { return autoDrainHoles || !drainHoles.empty(); }
};

/// "x,y,z,r" appends a hole to options.drainHoles; "auto" or "auto,R" sets options.autoDrainHoles (and its
/// radius R). @throws InvalidArgument naming --drain-hole and the text.
void parseDrainHoleSpec(const std::string& text, ShellOptions& options);

/// The holes of "x,y,z,r" texts (parseDrainHoleSpec without "auto", which needs the offset mesh: slice).
/// @throws InvalidArgument naming --drain-hole.
std::vector<DrainHole> parseDrainHoles(const std::vector<std::string>& texts);

struct ShellReport {
  double offset = 0.0;            ///< δ of the inner surface
  MeshTopology topology;          ///< of the shell mesh
  /// signedVolume of the shell mesh: the material's volume, > 0 for a correctly oriented solid.
  double volume = 0.0;
  double zeroVolume = 0.0;        ///< enclosed by the zero mesh
  double offsetVolume = 0.0;      ///< enclosed by the offset mesh (the cavities)
  double zeroMinusOffsetVolume() const noexcept { return zeroVolume - offsetVolume; }
  /// (volume − (zeroVolume − offsetVolume)) / (zeroVolume − offsetVolume): rounding only without holes,
  /// minus the holes' share of the material with them.
  double relativeDifference() const noexcept;
  bool intersectionsChecked = false;
  /// Intersecting triangle pairs of the shell mesh (MeshCheck::selfIntersections): the surfaces cross
  /// (or one of them intersects itself). A lower bound when intersectionsComplete is false.
  std::size_t intersections = 0;
  bool intersectionsComplete = false;
  bool intersects() const noexcept { return intersections > 0; }
  std::vector<DrainHole> drainHoles;  ///< the holes cut (given, then automatic)
  std::size_t droppedCavities = 0;    ///< small cavity components removed (minCavityFraction)
  double seconds = 0.0;
  /// Watertight, 2-manifold, oriented, positive volume, no intersection found (when checked, completely).
  bool valid() const noexcept;
};

struct ShellResult {
  Mesh mesh;  ///< outward normals everywhere: out of the part on the outer surface, into the cavity inside
  ShellReport report;
};

/// The shell of a zero-level mesh and the mesh of its inward offset δ = options.offset: zero's vertices and
/// faces, then the offset's with every face reversed. No holes (options.drained() is an error: they are cut
/// in the field, drainShell). @throws InvalidArgument (δ not > 0, holes, a bad index).
ShellResult buildShell(const Mesh& zero, const Mesh& offset, const ShellOptions& options);

/// The drained shell: {g' = 0} polygonized over `grid` with f from `field` (g' from drainedShellSamples),
/// small cavities dropped (minCavityFraction), the report as buildShell's; `zero` and `offset` (the
/// meshes of f = 0 and f = δ, best on the same grid) give zeroVolume, offsetVolume and the automatic holes.
/// Without holes the mesh is the shell {g = 0}. @throws InvalidArgument (δ not > 0, a hole's radius not
/// > 0 or a coordinate not finite, bad grid or options), Cancelled.
ShellResult drainShell(const FieldSampler& field, const GridSpec& grid, const Mesh& zero, const Mesh& offset,
                       const ShellOptions& options, const PolygonizeOptions& polygonize = {},
                       Interrupter* interrupter = nullptr);

}  // namespace duplexfit
