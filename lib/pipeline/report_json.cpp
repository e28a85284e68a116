// report.json of a pipeline run: the keys and structure the CLI has always written (tests and bench/*.py
// read them; add keys, never rename or remove one). nlohmann::ordered_json keeps the keys in this order;
// doubles are written with the shortest digits that round-trip, non-finite ones as null.
#include <sys/resource.h>

#include <nlohmann/json.hpp>
#include <algorithm>
#include <cmath>
#include <map>
#include <ostream>

#include "duplexfit/pipeline.hpp"

namespace duplexfit {

namespace {

using Json = nlohmann::ordered_json;

Json topologyJson(const MeshTopology& t) {
  return Json{{"vertices", t.vertices},
              {"faces", t.faces},
              {"components", t.components},
              {"watertight", t.watertight()},
              {"manifold", t.manifold()},
              {"oriented", t.oriented()},
              {"euler_characteristic", static_cast<long long>(t.eulerCharacteristic)}};
}

/// The fit's keys, added to `w`.
void addFitReport(Json& w, const FitReport& rep) {
  w["zero_normals"] = rep.zeroNormals;
  w["device"] = rep.device;
  w["device_tuning"] = rep.deviceTuning;
  w["precision"] = rep.precision;
  w["preconditioner"] = rep.preconditioner;
  w["assembly"] = rep.assembly;
  w["offsets"] = rep.offsets;
  w["off_surface_side"] = offSurfaceSideName(rep.offSurfaceSide);
  w["sigma0"] = rep.sigma0;
  w["sigma1"] = rep.sigma1;
  w["smoothing"] = rep.smoothing;
  w["levels"] = rep.levels;
  w["stopped_early"] = rep.stoppedEarly;
  Json levels = Json::array();
  for (const LevelReport& l : rep.levelReports) {
    levels.push_back(Json{
        {"level", l.level},
        {"sigma", l.sigma},
        {"surface_points", l.surfacePoints},
        {"offset_candidates", l.offsetCandidates},
        {"offset_kept", l.offsetKept},
        {"off_surface_candidates", l.offSurfaceCandidates},
        {"off_surface_kept", l.offSurfaceKept},
        {"offset_medial", l.offsetMedial},
        {"off_surface_medial", l.offSurfaceMedial},
        {"anchors",
         {{"inside", l.anchorsInside}, {"outside", l.anchorsOutside}, {"skipped", l.anchorsSkipped},
          {"spacing", l.anchorSpacing}}},
        {"merged_centres", l.mergedCentres},
        {"overshoot", {{"sites", l.overshootSites}, {"rounds", l.overshootRounds}, {"seconds", l.secondsOvershoot}}},
        {"centres", l.centres},
        {"nonzeros", l.nonZeros},
        {"max_residual_before", l.maxResidualBefore},
        {"cg",
         {{"converged", l.solve.converged}, {"stop_reason", stopReasonName(l.solve.reason)},
          {"iterations", l.solve.iterations}, {"relative_residual", l.solve.relativeResidual},
          {"tolerance", l.solve.tolerance}, {"max_residual", l.solve.maxResidual},
          {"absolute_tolerance", l.solve.absoluteTolerance},
          // Which tolerance the true residual met: the relative one, the absolute one (max |r_i|), or none.
          {"met", l.solve.converged && l.solve.reason == StopReason::Converged
                      ? (l.solve.relativeResidual <= l.solve.tolerance ? "relative" : "absolute")
                      : "none"}}},
        {"seconds",
         {{"constraints", l.secondsConstraints}, {"residual", l.secondsResidual}, {"assembly", l.secondsAssembly},
          {"solve", l.secondsSolve}}}});
  }
  w["level_reports"] = std::move(levels);
  w["E0"] = rep.e0;
  w["Edelta"] = rep.eDelta;
  const OffsetCorrectionReport& c = rep.correction;
  w["offset_correction"] = Json{{"applied", c.applied},         {"sigma", c.sigma},
                                {"points", c.points},           {"nonzeros", c.nonZeros},
                                {"mean_before", c.meanBefore},  {"max_before", c.maxBefore},
                                {"cg_iterations", c.solve.iterations}, {"cg_converged", c.solve.converged},
                                {"seconds", c.seconds}};
  w["winding_seconds"] = rep.secondsWinding;
}

Json vec3(const Eigen::Vector3d& v) { return Json::array({v.x(), v.y(), v.z()}); }

/// A mesh's cleaning, simplification and deviation from its level set (finishSurfaces).
void addFinishReport(Json& m, const MeshFinishReport& f) {
  const CleanReport& c = f.clean;
  m["cleaning"] = Json{{"applied", c.facesBefore > 0},
                       {"faces_before", c.facesBefore},
                       {"faces_after", c.facesAfter},
                       {"vertices_before", c.verticesBefore},
                       {"vertices_after", c.verticesAfter},
                       {"collapses", c.collapses},
                       {"flips", c.flips},
                       {"refused_topology", c.refusedTopology},
                       {"refused_geometry", c.refusedGeometry},
                       {"refused_crossing", c.refusedCrossing},
                       {"refused_flips", c.refusedFlips},
                       {"locked_vertices", c.lockedVertices},
                       {"float32_degenerate_before", c.float32DegenerateBefore},
                       {"float32_degenerate_after", c.float32DegenerateAfter},
                       {"slivers_before", c.sliversBefore},
                       {"slivers_after", c.sliversAfter},
                       {"min_angle_before", c.minAngleBefore},
                       {"min_angle_after", c.minAngleAfter},
                       {"shortest_edge_before", c.shortestEdgeBefore},
                       {"shortest_edge_after", c.shortestEdgeAfter},
                       {"seconds", c.seconds}};
  const SimplifyReport& s = f.simplify;
  m["simplification"] = Json{{"applied", s.applied},
                             {"faces_before", s.facesBefore},
                             {"faces_after", s.facesAfter},
                             {"target_error", s.targetError},
                             {"result_error", s.resultError},
                             {"duplicate_pairs_removed", s.duplicatePairsRemoved},
                             {"fallback", s.fallback},
                             {"topology_kept", s.topologyKept},
                             {"seconds", s.seconds}};
  const ProjectReport& p = f.project;
  m["projection"] = Json{{"applied", p.applied},
                         {"faces_before", p.facesBefore},
                         {"faces_after", p.facesAfter},
                         {"vertices_before", p.verticesBefore},
                         {"vertices_after", p.verticesAfter},
                         {"moved", p.moved},
                         {"partial", p.partial},
                         {"refused", p.refused},
                         {"not_converged", p.notConverged},
                         {"splits", p.splits},
                         {"rounds", p.rounds},
                         {"faces_left_beyond_target", p.markedLeft},
                         {"centres_evaluated", p.centresEvaluated},
                         {"centres_predicted", p.centresPredicted},
                         {"self_intersections_found", p.selfIntersectionsFound},
                         {"self_intersections_checked", p.selfIntersectionsChecked},
                         {"self_intersections_left", p.selfIntersectionsLeft},
                         {"reverted", p.reverted},
                         {"seconds", p.seconds}};
  const NeckPassReport& n = f.neckPass;
  m["neck_pass"] = Json{{"applied", n.applied},
                        {"kept", n.kept},
                        {"cells", n.cells},
                        {"too_many_cells", n.tooManyCells},
                        {"faces_before", n.facesBefore},
                        {"faces_after", n.facesAfter},
                        {"max_before", n.maxBefore},
                        {"max_after", n.maxAfter},
                        {"local", n.local},
                        {"removed_faces", n.removedFaces},
                        {"patch_faces", n.patchFaces},
                        {"local_refused", n.localRefused},
                        {"seconds", n.seconds}};
  Json deviation;  // null when not measured
  if (f.deviationMeasured) {
    const LevelSetDeviation& d = f.deviation;
    deviation = Json{{"candidates", d.candidates},
                     {"samples", d.samples},
                     {"flat_samples", d.flatSamples},
                     {"refined_samples", d.refinedSamples},
                     {"local_samples", d.localSamples},
                     {"max", d.max},
                     {"mean", d.mean},
                     {"rms", d.rms},
                     {"p99", d.p99},
                     {"p999", d.p999},
                     {"max_at", vec3(d.maxAt)},
                     {"side", d.side},
                     {"max_relative", d.relativeMax},
                     {"p99_relative", d.side > 0.0 ? d.p99 / d.side : 0.0},
                     {"limit", d.limit},
                     {"above_limit", d.aboveLimit},
                     {"seconds", d.seconds}};
  }
  m["level_set_deviation"] = std::move(deviation);
}

Json droppedJson(const DroppedComponents& d) {
  return Json{{"components", d.components}, {"faces", d.faces},
              {"area", d.area}, {"area_fraction", d.areaFraction},
              {"min_area_fraction", d.minAreaFraction}};
}

Json selfCheckJson(const SelfCheckReport& r, const std::vector<std::string>& meshNames) {
  Json surfaces = Json::array();
  for (const SurfaceSelfCheck& s : r.surfaces) {
    Json j{{"surface", s.surface},
           {"file", meshNames[static_cast<std::size_t>(s.surface)]},
           {"iso", s.iso},
           {"components", s.components},
           {"faces", s.faces},
           {"area", s.area},
           {"issues", s.issues},
           {"dropped", droppedJson(s.dropped)}};
    if (std::isfinite(s.thinnestWall) && s.iso != 0.0) {
      j["thinnest_wall"] = s.thinnestWall;
      j["thinnest_wall_relative"] = s.thinnestWall / std::abs(s.iso);
      j["thinnest_wall_at"] = {s.thinnestWallAt.x(), s.thinnestWallAt.y(), s.thinnestWallAt.z()};
    }
    surfaces.push_back(std::move(j));
  }
  Json issues = Json::array();
  for (const ComponentIssue& i : r.issues) {
    issues.push_back(Json{{"surface", i.surface},
                          {"file", meshNames[static_cast<std::size_t>(i.surface)]},
                          {"iso", i.iso},
                          {"component", i.component},
                          {"why", componentIssueName(i.why)},
                          {"faces", i.faces},
                          {"vertices", i.vertices},
                          {"area", i.area},
                          {"area_fraction", i.areaFraction},
                          {"box", {{"min", vec3(i.box.min())}, {"max", vec3(i.box.max())}}},
                          {"mean_distance", i.meanDistance},
                          {"mean_deviation", i.meanDeviation},
                          {"nearest_input_point", i.nearestInputPoint}});
  }
  return Json{{"ok", r.ok()},
              {"points_checked", r.pointsChecked},
              {"point_tolerance", r.pointTolerance},
              {"min_component", r.minAreaFraction},
              {"min_offset_component", r.minOffsetAreaFraction},
              {"surfaces", std::move(surfaces)},
              {"issues", std::move(issues)},
              {"seconds", r.seconds}};
}

/// The shell's volumes, intersections, validity and drain holes (report.json's "shell" and mesh --shell --json).
void addShellFigures(Json& j, const ShellReport& r) {
  Json holes = Json::array();
  for (const DrainHole& h : r.drainHoles) holes.push_back(Json{{"point", vec3(h.point)}, {"radius", h.radius}});
  j["volume"] = r.volume;
  j["zero_volume"] = r.zeroVolume;
  j["offset_volume"] = r.offsetVolume;
  j["zero_minus_offset_volume"] = r.zeroMinusOffsetVolume();
  j["relative_difference"] = r.relativeDifference();
  j["intersections_checked"] = r.intersectionsChecked;
  j["intersections_complete"] = r.intersectionsComplete;
  j["intersecting_pairs"] = r.intersections;
  j["intersects"] = r.intersects();
  j["valid"] = r.valid();
  j["drain_holes"] = std::move(holes);
}

Json shellJson(const PipelineResult& result, const std::vector<std::string>& meshNames, const std::string& format) {
  if (!result.shell) return Json();  // null: no shell asked for
  const PipelineShell& s = *result.shell;
  const ShellReport& r = s.report;
  Json j{{"file", pipelineShellName(format)},
         {"offset", r.offset},
         {"inner_surface", meshNames[s.surface]},
         {"note", s.note},
         {"faces", r.topology.faces},
         {"watertight", r.topology.watertight()},
         {"manifold", r.topology.manifold()},
         {"oriented", r.topology.oriented()},
         {"topology", topologyJson(r.topology)}};
  addShellFigures(j, r);
  j["dropped_cavities"] = r.droppedCavities;
  j["seconds"] = r.seconds;
  return j;
}

/// The local refinement's counts (PolygonizeStats).
Json refinementJson(const PolygonizeStats& s) {
  return Json{{"thin_cells", s.thinCells},
              {"deviating_cells", s.deviatingCells},
              {"shallow_cells", s.shallowCells},
              {"seed_cells", s.refinedSeeds},
              {"cells", s.refinedCells},
              {"tetrahedra", s.refinedTetrahedra},
              {"evaluations", s.refinedEvaluations},
              {"skipped", s.refinementSkipped},
              {"seconds", s.refinedSeconds}};
}

Json gridJson(const SurfaceResult& e) {
  return Json{{"cells", Json::array({e.grid.cells.x(), e.grid.cells.y(), e.grid.cells.z()})},
              {"cell", e.grid.cellSize().maxCoeff()},
              {"evaluated_fraction", e.stats.evaluatedFraction()},
              {"refinement", refinementJson(e.stats)},
              {"sampler_seconds", e.stats.samplingSeconds},
              {"extraction_seconds", e.stats.extractionSeconds}};
}

/// A mesh input's checks and sampling (null for a cloud).
Json inputMeshJson(const PipelineReport& report) {
  if (!report.mesh) return Json();
  const MeshSampleReport& m = *report.mesh;
  const MeshTopology& t = m.topology;
  return Json{{"format", meshFormatName(report.meshFormat)},
              {"vertices", t.vertices},
              {"faces", t.faces},
              {"area", m.area},
              {"largest_side", m.largestSide},
              {"components", t.components},
              {"watertight", t.watertight()},
              {"manifold", t.manifold()},
              {"oriented", t.oriented()},
              {"boundary_edges", t.boundaryEdges},
              {"non_manifold_edges", t.nonManifoldEdges},
              {"non_manifold_vertices", t.nonManifoldVertices},
              {"inconsistent_edges", t.inconsistentEdges},
              {"degenerate_faces", m.degenerateFaces},
              {"first_boundary_face", m.firstBoundaryFace},
              {"first_non_manifold_face", m.firstNonManifoldFace},
              {"first_inconsistent_faces", {m.firstInconsistentFaces[0], m.firstInconsistentFaces[1]}},
              {"orientation", meshOrientationName(m.orientation)},
              {"reoriented_faces", m.reorientedFaces},
              {"inconsistent_after", m.inconsistentAfter},
              {"signed_volume", m.signedVolume},
              {"flipped", m.flipped},
              {"density_rule", m.densityRule},
              {"requested_spacing", m.requestedSpacing},
              {"clamped", m.clamped},
              {"samples", m.samples},
              {"spacing", m.spacing},
              {"warnings", m.warnings},
              {"seconds", m.seconds}};
}

}  // namespace

void writeMeshPipelineJson(std::ostream& out, const MeshPipelineResult& result, const std::string& outputPath,
                           double iso) {
  Json m{{"file", outputPath}, {"iso", iso}, {"topology", topologyJson(result.topology)},
         {"dropped", droppedJson(result.dropped)}, {"grid", gridJson(result.extraction)}};
  addFinishReport(m, result.finish);
  out << m.dump(2) << "\n";
}

void writeShellPipelineJson(std::ostream& out, const ShellPipelineResult& result, const std::string& outputPath) {
  const ShellReport& r = result.shell.report;
  Json m{{"file", outputPath}, {"offset", r.offset}, {"note", result.note}, {"topology", topologyJson(r.topology)}};
  addShellFigures(m, r);
  m["dropped_zero"] = droppedJson(result.droppedZero);
  m["dropped_offset"] = droppedJson(result.droppedOffset);
  m["grid"] = gridJson(result.extraction);
  m["seconds"] = r.seconds;
  out << m.dump(2) << "\n";
}

void writePipelineReport(std::ostream& out, const PipelineResult& result, const std::string& meshFormat,
                         double writeSeconds) {
  const PipelineReport& report = result.report;
  const FitReport& rep = report.fit;
  const bool separate = report.separate;
  const std::vector<std::string> meshNames = pipelineMeshNames(result, meshFormat);
  const std::vector<std::string> fieldNames = pipelineFieldNames(result);
  Json w;
  w["input"] = report.input;
  w["input_mesh"] = inputMeshJson(report);
  w["points"] = report.read.points;
  w["duplicates_merged"] = report.duplicatesMerged;
  w["mode"] = separate ? "separate" : "duplex";
  w["side_test"] = report.sideTest;
  w["crease_test"] = report.creaseTest;
  Json normals;  // null unless estimated
  if (report.normals) {
    const NormalReport& n = *report.normals;
    normals = Json{{"method", "PCA + Riemannian MST propagation + enclosed-volume sign"},
                   {"k", n.k},
                   {"graph_k", n.graphK},
                   {"input_had_normals", report.read.normals},
                   {"components", n.components},
                   {"flipped_components", n.flippedComponents},
                   {"ambiguous_components", n.ambiguousComponents},
                   {"nested_components", n.nestedComponents},
                   {"degenerate", n.degenerate},
                   {"non_planar", n.nonPlanar},
                   {"seconds", n.seconds}};
  }
  Json distributed;  // null unless the fit was distributed
  if (report.distributed) {
    const DistributedReport& d = *report.distributed;
    // One entry per block, and per rank the sums over its blocks (with one block per rank, the same).
    Json blocks = Json::array();
    std::map<int, Json> ranksByIndex;
    std::map<int, int> blocksOfRank;
    for (const DistributedRankReport& r : d.rankReports) ++blocksOfRank[r.rank];
    for (const DistributedRankReport& r : d.rankReports) {
      Json levels = Json::array();
      std::size_t halo = 0, unknowns = 0, nonZeros = 0;
      int iterations = 0;
      for (const DistributedLevelReport& l : r.levels) {
        levels.push_back(Json{{"level", l.level},
                              {"gathered", l.gathered},
                              {"level_points", l.levelPoints},
                              {"halo_points", l.haloPoints},
                              {"unknowns", l.unknowns},
                              {"ghosts", l.ghosts},
                              {"owned_centres", l.ownedCentres},
                              {"non_zeros", l.nonZeros},
                              {"cg_iterations", l.iterations},
                              {"bytes_received", l.bytes},
                              {"seconds", l.seconds},
                              {"seconds_solve", l.secondsSolve}});
        halo = std::max(halo, l.haloPoints);
        unknowns += l.unknowns;
        nonZeros += l.nonZeros;
        iterations += l.iterations;
      }
      blocks.push_back(Json{{"block", r.block},
                            {"rank", r.rank},
                            {"points", r.points},
                            {"halo_points", halo},
                            {"unknowns", unknowns},
                            {"non_zeros", nonZeros},
                            {"cg_iterations", iterations},
                            {"peak_bytes", r.peakBytes},
                            {"levels", levels}});
      Json& rank = ranksByIndex[r.rank];
      if (rank.is_null()) {
        rank = Json{{"rank", r.rank},
                    {"blocks", blocksOfRank[r.rank]},
                    {"read_rows", std::size_t{0}},
                    {"points", std::size_t{0}},
                    {"halo_points", std::size_t{0}},
                    {"unknowns", std::size_t{0}},
                    {"non_zeros", std::size_t{0}},
                    {"cg_iterations", 0},
                    {"bytes_received", std::uint64_t{0}},
                    {"seconds_partition", r.secondsPartition},
                    {"seconds_fit", r.secondsFit},
                    {"peak_bytes", std::uint64_t{0}}};
        if (blocksOfRank[r.rank] == 1) rank["levels"] = levels;
      }
      rank["read_rows"] = rank["read_rows"].get<std::size_t>() + r.readRows;
      rank["points"] = rank["points"].get<std::size_t>() + r.points;
      rank["halo_points"] = std::max(rank["halo_points"].get<std::size_t>(), halo);
      rank["unknowns"] = rank["unknowns"].get<std::size_t>() + unknowns;
      rank["non_zeros"] = rank["non_zeros"].get<std::size_t>() + nonZeros;
      rank["cg_iterations"] = rank["cg_iterations"].get<int>() + iterations;
      rank["bytes_received"] = rank["bytes_received"].get<std::uint64_t>() + r.bytesReceived;
      rank["peak_bytes"] = std::max(rank["peak_bytes"].get<std::uint64_t>(), r.peakBytes);
    }
    Json ranks = Json::array();
    for (auto& [index, rank] : ranksByIndex) ranks.push_back(std::move(rank));
    distributed = Json{{"mode", distributedModeName(d.mode)},
                       {"halo", d.halo},
                       {"ranks", d.ranks},
                       {"blocks", d.blocks},
                       {"communicator", d.communicator},
                       {"coarse_points", d.coarsePoints},
                       {"file_rows", d.fileRows},
                       {"owned_rows", d.ownedRows},
                       {"owned_once", d.ownedOnce},
                       {"sigma0_approximate", d.sigma0Approximate},
                       {"winding_proxy_points", d.windingProxyPoints},
                       {"per_rank", ranks},
                       {"per_block", blocks}};
  }
  if (report.distributedExtraction && !distributed.is_null()) {
    const DistributedExtractionReport& x = *report.distributedExtraction;
    Json slabs = Json::array();
    for (const SlabExtractionReport& r : x.ranks) {
      slabs.push_back(Json{{"rank", r.rank},
                           {"slab", Json::array({r.slabBegin, r.slabEnd})},
                           {"evaluated_nodes", r.evaluatedNodes},
                           {"refined_cells", r.refinedCells},
                           {"triangles", r.triangles},
                           {"bytes_sent", r.bytesSent},
                           {"seconds", r.seconds}});
    }
    distributed["extraction"] = Json{{"per_rank", slabs}, {"weld_seconds", x.weldSeconds}};
  }
  w["distributed"] = distributed;
  Json denoise;
  if (report.denoise) {
    const BilateralReport& b = *report.denoise;
    denoise = Json{{"method", "bilateral point filter (docs/method.md section 9)"},
                   {"reason", report.denoisedForNoise ? "noisy input (the noise estimate)" : "asked (--denoise)"},
                   {"sigma_spatial", b.sigmaSpatial},
                   {"sigma_range", b.sigmaRange},
                   {"radius", b.radius},
                   {"area_sigma", b.areaSigma},
                   {"iterations", b.iterations},
                   {"symmetric_range", b.symmetricRange},
                   {"mean_neighbors", b.meanNeighbors},
                   {"moved", b.moved},
                   {"max_displacement", b.maxDisplacement},
                   {"mean_displacement", b.meanDisplacement},
                   {"seconds", b.seconds}};
  }
  const OutlierReport& o = report.outliers;
  Json outliers{{"method", "beyond the box of the bulk (per-axis quantiles) by more than margin x its size, or "
                          "k-th neighbour distance above isolation_factor x the cloud's median"},
                {"quantile", o.quantile},
                {"margin", o.margin},
                {"neighbours", o.neighbours},
                {"isolation_factor", o.isolationFactor},
                {"median_neighbour_distance", o.medianNeighbourDistance},
                {"count", o.indices.size()},
                {"outside_box", o.outsideBox},
                {"isolated", o.isolated},
                {"removed", report.outliersRemoved},
                {"bulk_min", {o.bulkMin.x(), o.bulkMin.y(), o.bulkMin.z()}},
                {"bulk_max", {o.bulkMax.x(), o.bulkMax.y(), o.bulkMax.z()}}};
  if (!o.indices.empty()) {
    if (o.outsideBox > 0) {
      outliers["worst_point"] = o.worst;
      outliers["worst_distance"] = o.worstDistance;
    }
    if (o.isolated > 0) {
      outliers["most_isolated_point"] = o.mostIsolated;
      outliers["worst_isolation"] = o.worstIsolation;
    }
    Json first = Json::array();
    for (std::size_t i = 0; i < std::min<std::size_t>(o.indices.size(), 20); ++i) first.push_back(o.indices[i]);
    outliers["first_points"] = std::move(first);
  }
  const NoiseEstimate& ne = report.noise;
  Json noise{{"method", "median over evenly strided samples of the RMS distance of each sample and its nearest "
                        "neighbours from their least-squares plane, in median nearest-neighbour distances"},
             {"ratio", ne.ratio},
             {"spacing", ne.spacing},
             {"samples", ne.samples},
             {"threshold", ne.threshold},
             {"noisy", ne.noisy()}};
  w["preprocessing"] = Json{{"normals", std::move(normals)}, {"denoise", std::move(denoise)}, {"outliers", std::move(outliers)},
                            {"noise", std::move(noise)}};
  if (!separate) {
    addFitReport(w, rep);
  } else {
    w["device"] = rep.device;
    w["precision"] = rep.precision;
    w["offsets"] = rep.offsets;
    w["E0"] = rep.e0;
    w["Edelta"] = rep.eDelta;
    Json fits = Json::array();
    for (std::size_t i = 0; i < report.separateFits.size(); ++i) {
      Json f{{"surface", i == 0 ? std::string("zero") : "offset" + std::to_string(i)},
             {"delta", i == 0 ? 0.0 : rep.offsets[i - 1]},
             {"fitted_points", report.separateFittedPoints[i]}};
      addFitReport(f, report.separateFits[i]);
      fits.push_back(std::move(f));
    }
    w["fits"] = std::move(fits);
  }
  Json meshes = Json::array();
  for (std::size_t i = 0; i < result.surfaces.size(); ++i) {
    const PipelineSurface& s = result.surfaces[i];
    Json m{{"file", meshNames[i]},
           {"iso", s.iso},
           {"field", fieldNames[s.field]},
           {"topology", topologyJson(s.topology)},
           // What `check` counts beside the topology; sound is what `fit --strict` asks of the mesh.
           {"quality", Json{{"float32_degenerate", s.quality.float32DegenerateFaces},
                            {"slivers", s.quality.slivers},
                            {"min_angle", s.quality.minAngle}}},
           {"sound", s.sound()}};
    addFinishReport(m, s.finish);
    meshes.push_back(std::move(m));
  }
  w["meshes"] = std::move(meshes);
  w["self_check"] = selfCheckJson(report.selfCheck, meshNames);
  const PhantomRepairReport& pr = report.phantomRepair;
  w["phantom_repair"] = Json{{"candidates", pr.candidates},   {"repaired", pr.repaired},
                             {"repaired_faces", pr.repairedFaces}, {"offset_faces", pr.offsetFaces},
                             {"not_phantom", pr.notPhantom},
                             {"anchors", pr.anchors},         {"keep_points", pr.keepPoints},
                             {"restored_keep_points", pr.restored},
                             {"max_change", pr.maxChange},    {"max_deviation", pr.maxDeviation},
                             {"rounds", pr.rounds}, {"iterations", pr.iterations},
                             {"refused_phantoms", pr.refusedPhantoms}, {"first_refusal", pr.firstRefusal},
                             {"refused", pr.refused},         {"reextracted", pr.reextracted},
                             {"reextract_seconds", pr.reextractSeconds},
                             {"seconds", pr.seconds}};
  w["shell"] = shellJson(result, meshNames, meshFormat);
  w["grid"] = Json{{"nx", report.grid.cells.x()},
                   {"ny", report.grid.cells.y()},
                   {"nz", report.grid.cells.z()},
                   {"cell", report.grid.cellSize().maxCoeff()},
                   {"evaluated_fraction", report.gridStats.evaluatedFraction()},
                   {"box_growths", report.boxGrowths},
                   {"continued_cells", report.gridStats.continuedCells},
                   {"reused_chunks", report.gridStats.reusedChunks},
                   {"extraction_rounds", report.gridStats.extractionRounds},
                   {"refinement", refinementJson(report.gridStats)},
                   {"touches_boundary", report.touchesBoundary},
                   {"sampler_seconds", report.gridStats.samplerSeconds},
                   {"extraction_seconds", report.gridStats.extractionSeconds}};
  w["seconds"] = Json{{"read", report.secondsRead},
                      {"hierarchy", rep.secondsHierarchy},
                      {"fit", rep.secondsTotal},
                      {"polygonize", report.secondsPolygonize},
                      {"finish", report.secondsFinish},
                      {"write", writeSeconds},
                      {"total", report.secondsTotal + writeSeconds}};
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  w["peak_rss_mib"] = static_cast<double>(usage.ru_maxrss) / 1024.0;
  // Paths are bytes: invalid UTF-8 is replaced (U+FFFD) instead of failing the whole report.
  out << w.dump(2, ' ', false, Json::error_handler_t::replace) << '\n';
}

}  // namespace duplexfit
