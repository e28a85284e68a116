// report.json of a pipeline run: the keys and structure the CLI has always written (tests and bench/*.py
// read them; add keys, never rename or remove one). nlohmann::ordered_json keeps the keys in this order;
// doubles are written with the shortest digits that round-trip, non-finite ones as null.
#include <sys/resource.h>

#include <nlohmann/json.hpp>
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
  w["precision"] = rep.precision;
  w["offsets"] = rep.offsets;
  w["off_surface_side"] = offSurfaceSideName(rep.offSurfaceSide);
  w["sigma0"] = rep.sigma0;
  w["sigma1"] = rep.sigma1;
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
        {"centres", l.centres},
        {"nonzeros", l.nonZeros},
        {"max_residual_before", l.maxResidualBefore},
        {"cg",
         {{"converged", l.solve.converged}, {"stop_reason", stopReasonName(l.solve.reason)},
          {"iterations", l.solve.iterations}, {"relative_residual", l.solve.relativeResidual},
          {"tolerance", l.solve.tolerance}}},
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

Json selfCheckJson(const SelfCheckReport& r, const std::vector<std::string>& meshNames) {
  Json surfaces = Json::array();
  for (const SurfaceSelfCheck& s : r.surfaces) {
    surfaces.push_back(Json{{"surface", s.surface},
                            {"file", meshNames[static_cast<std::size_t>(s.surface)]},
                            {"iso", s.iso},
                            {"components", s.components},
                            {"faces", s.faces},
                            {"area", s.area},
                            {"issues", s.issues},
                            {"dropped",
                             {{"components", s.dropped.components}, {"faces", s.dropped.faces},
                              {"area", s.dropped.area}, {"area_fraction", s.dropped.areaFraction}}}});
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

}  // namespace

void writePipelineReport(std::ostream& out, const PipelineResult& result, const std::string& meshFormat,
                         double writeSeconds) {
  const PipelineReport& report = result.report;
  const FitReport& rep = report.fit;
  const bool separate = report.separate;
  const std::vector<std::string> meshNames = pipelineMeshNames(result, meshFormat);
  const std::vector<std::string> fieldNames = pipelineFieldNames(result);
  Json w;
  w["input"] = report.input;
  w["points"] = report.read.points;
  w["duplicates_merged"] = report.duplicatesMerged;
  w["mode"] = separate ? "separate" : "duplex";
  w["side_test"] = report.sideTest;
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
  Json denoise;
  if (report.denoise) {
    const BilateralReport& b = *report.denoise;
    denoise = Json{{"method", "bilateral point filter (docs/method.md section 9)"},
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
  w["preprocessing"] = Json{{"normals", std::move(normals)}, {"denoise", std::move(denoise)}};
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
    meshes.push_back(Json{{"file", meshNames[i]},
                          {"iso", s.iso},
                          {"field", fieldNames[s.field]},
                          {"topology", topologyJson(s.topology)}});
  }
  w["meshes"] = std::move(meshes);
  w["self_check"] = selfCheckJson(report.selfCheck, meshNames);
  w["grid"] = Json{{"nx", report.grid.cells.x()},
                   {"ny", report.grid.cells.y()},
                   {"nz", report.grid.cells.z()},
                   {"cell", report.grid.cellSize().maxCoeff()},
                   {"evaluated_fraction", report.gridStats.evaluatedFraction()},
                   {"box_growths", report.boxGrowths},
                   {"continued_cells", report.gridStats.continuedCells},
                   {"touches_boundary", report.touchesBoundary},
                   {"sampler_seconds", report.gridStats.samplerSeconds},
                   {"extraction_seconds", report.gridStats.extractionSeconds}};
  w["seconds"] = Json{{"read", report.secondsRead},
                      {"hierarchy", rep.secondsHierarchy},
                      {"fit", rep.secondsTotal},
                      {"polygonize", report.secondsPolygonize},
                      {"write", writeSeconds},
                      {"total", report.secondsTotal + writeSeconds}};
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  w["peak_rss_mib"] = static_cast<double>(usage.ru_maxrss) / 1024.0;
  // Paths are bytes: invalid UTF-8 is replaced (U+FFFD) instead of failing the whole report.
  out << w.dump(2, ' ', false, Json::error_handler_t::replace) << '\n';
}

}  // namespace duplexfit
