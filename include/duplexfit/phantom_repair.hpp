// Phantom repair (docs/method.md, "Phantom repair"): a zero-level component that carries no input point and
// whose inside the cloud's winding number calls empty space (or whose outside it calls solid) is phantom
// solid the coarse levels left in a pocket or narrow gap, too near the samples for the sign anchors' band.
// The repair adds centres of the finest level's support there: sign anchors on a fine grid over the
// component with the signed distance to the cloud as target, and centres that keep f where it is at the
// input points, their offset companions and off-surface points around them. A phantom's correction is
// kept only when its anchors' signs hold, f has the surroundings' sign on a grid over the component, and
// the other meshes' vertices near it follow their level sets by a bounded move without turning a face (or,
// with reextractMeshes, a mesh they cannot follow is handed back to be extracted again there); a phantom
// that fails is left out and the others are solved again without it.
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/device.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/mesh.hpp"
#include "duplexfit/self_check.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit {

struct PhantomRepairOptions {
  /// Candidates: components of the zero-level mesh with no input point within this many mean edge lengths
  /// (the pipeline asks its self-check for them: SelfCheckOptions::candidateEdges).
  double candidateEdges = 1.0;
  /// The anchors' grid spacing, × σ_M (the finest level's support).
  double anchorSpacing = 0.25;
  /// The anchors' grid covers the component's box enlarged by this × σ_M on every side: the phantom's pull
  /// on f reaches about σ_M beyond it (wheel_29k's void at δ = 0.01 left a bump of the offset 0.005 deep
  /// with σ_M/4).
  double boxMargin = 0.5;
  /// Anchors whose distance to the samples lies within this × σ_M of an offset |δ_j| are skipped (the
  /// fit's own anchors keep σ_M/2: at σ_M/2 no anchor pinned the part of wheel_29k's void's bump next to
  /// the offset).
  double offsetClearance = 0.125;
  /// Anchors lie at least this fraction of the component's distance to the input points from every point.
  double minDistanceFraction = 0.5;
  /// Input points within this × σ_M of an anchor keep f (with their offset and off-surface companions).
  double keepRadius = 2.0;
  /// More correction centres than this: refused (a phantom that large is not a pocket's).
  std::size_t maxCentres = 50000;
  /// The other meshes' vertices within σ_M of a correction centre follow their level sets: by at most this
  /// fraction of the largest side of the input's box (five times the neck pass's deviation limit), unless
  /// the vertex ends within it of the mesh's old vertices or of its distance to the samples (|δ_j|, the
  /// disk-soup distance), or nearer to that distance than it started (a part of the level set that went
  /// with the phantom, not a shift of the rest).
  double maxChange = 5e-3;
  /// When a mesh's vertices near the correction cannot follow their level set (a path that finds none, a
  /// face that would turn: the level set there changed its shape, as around a phantom void's offset),
  /// hand that mesh back for extraction again around the correction (PhantomRepairResult::reextract)
  /// rather than refuse the phantom. The pipeline does; false keeps every result a set of moves.
  bool reextractMeshes = false;
};

struct PhantomRepairReport {
  std::size_t candidates = 0;    ///< zero-level components with no input point near them
  std::size_t repaired = 0;      ///< of them, removed from the field (and from the mesh by the caller)
  std::size_t repairedFaces = 0; ///< their faces
  std::size_t offsetFaces = 0;   ///< faces of the offset meshes' components inside them, removed too
  std::size_t notPhantom = 0;    ///< candidates whose anchors all agree with f's sign (left alone)
  std::size_t anchors = 0;       ///< correction centres with a signed-distance target
  std::size_t keepPoints = 0;    ///< correction centres that keep f where it was (or get the fit's value back)
  std::size_t restored = 0;      ///< of them, those the phantom had pulled off the fit's value, which get it back
  double maxChange = 0.0;        ///< the largest move of the other meshes' vertices near the correction (input units)
  double maxDeviation = 0.0;     ///< their largest |f − iso|/|∇f| after it (input units)
  int iterations = 0;            ///< CG iterations over the rounds
  int rounds = 0;                ///< solves (a node where f kept the phantom's sign is an anchor of the next)
  std::size_t refusedPhantoms = 0; ///< phantoms left as they were (a check failed at their correction)
  std::size_t reextracted = 0;   ///< meshes handed back for extraction again around the correction
  double reextractSeconds = 0.0; ///< the caller's extraction again (the pipeline sets it; not in `seconds`)
  std::string firstRefusal;      ///< why the first phantom left out was (the others were repaired without it)
  std::string refused;           ///< empty, or why the field was left as it was (no phantom repaired)
  double seconds = 0.0;
};

struct PhantomRepairResult {
  PhantomRepairReport report;
  std::optional<ImplicitField> field;  ///< the repaired field (set when report.repaired > 0)
  /// An evaluator of `field` on the device and in the precision given (set with it; the checks built it).
  std::shared_ptr<const FieldEvaluator> evaluator;
  /// Per mesh, the faces to remove (ascending): of meshes[0] the repaired components', of an offset mesh
  /// its components inside a phantom whose level the repair removed too (a bump above δ holds a δ level).
  std::vector<std::vector<Index>> removedFaces;
  /// Per mesh: the vertices near the correction moved onto their level sets of the repaired field (index,
  /// new position), to be applied before removing the faces.
  std::vector<std::vector<std::pair<Index, Eigen::Vector3d>>> moves;
  /// Per mesh (with PhantomRepairOptions::reextractMeshes): empty, or the positions (input units) of its
  /// vertices within σ_M of a correction centre, where the caller extracts its level set of the repaired
  /// field again (the mesh then has no moves). The caller must refuse the whole repair when it cannot.
  std::vector<std::vector<Eigen::Vector3d>> reextract;
};

/// Repairs the phantoms among `candidates` (components of meshes[0] without input points near them: the
/// self-check's SelfCheckReport::emptyComponents, or emptyZeroLevelComponents) in the field's finest level.
/// meshes[0] is the zero level of `field`, meshes[j] its level isos[j] (input units); `points` and
/// `outwardNormals` the fitted cloud (input units); `evaluator` evaluates `field` (all its levels). The
/// field and the meshes are not modified: the result says what to change.
/// @throws InvalidArgument on mismatched sizes, a field without levels or options out of range.
PhantomRepairResult repairPhantoms(const Device& device, Precision precision, const ImplicitField& field,
                                   const FieldEvaluator& evaluator, const Points& points, const Points& outwardNormals,
                                   const std::vector<Mesh>& meshes, const std::vector<double>& isos,
                                   const std::vector<EmptyComponent>& candidates, const PhantomRepairOptions& options = {});

}  // namespace duplexfit
