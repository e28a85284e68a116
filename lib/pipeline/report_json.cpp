// report.json of a pipeline run: the keys and structure the CLI has always written (tests and bench/*.py
// read them; add keys, never rename or remove one).
#include <sys/resource.h>

#include <ostream>

#include "duplexfit/pipeline.hpp"
#include "pipeline/json_writer.hpp"

namespace duplexfit {

namespace {

using detail::JsonWriter;

void writeTopology(JsonWriter& w, const MeshTopology& t) {
  w.beginObject()
      .field("vertices", t.vertices)
      .field("faces", t.faces)
      .field("components", t.components)
      .field("watertight", t.watertight())
      .field("manifold", t.manifold())
      .field("oriented", t.oriented())
      .field("euler_characteristic", static_cast<long long>(t.eulerCharacteristic))
      .endObject();
}

void writeFitReport(JsonWriter& w, const FitReport& rep) {
  w.field("zero_normals", rep.zeroNormals).field("device", rep.device).field("precision", rep.precision);
  w.key("offsets").beginArray();
  for (double d : rep.offsets) w.value(d);
  w.endArray();
  w.field("off_surface_side", rep.offSurfaceSide).field("sigma0", rep.sigma0).field("sigma1", rep.sigma1);
  w.field("levels", rep.levels).field("stopped_early", rep.stoppedEarly);
  w.key("level_reports").beginArray();
  for (const LevelReport& l : rep.levelReports) {
    w.beginObject().field("level", l.level).field("sigma", l.sigma).field("surface_points", l.surfacePoints);
    w.key("offset_candidates").beginArray();
    for (auto v : l.offsetCandidates) w.value(v);
    w.endArray().key("offset_kept").beginArray();
    for (auto v : l.offsetKept) w.value(v);
    w.endArray();
    w.field("off_surface_candidates", l.offSurfaceCandidates).field("off_surface_kept", l.offSurfaceKept);
    w.key("offset_medial").beginArray();
    for (auto v : l.offsetMedial) w.value(v);
    w.endArray().field("off_surface_medial", l.offSurfaceMedial);
    w.key("anchors").beginObject().field("inside", l.anchorsInside).field("outside", l.anchorsOutside);
    w.field("skipped", l.anchorsSkipped).field("spacing", l.anchorSpacing).endObject();
    w.field("merged_centres", l.mergedCentres).field("centres", l.centres).field("nonzeros", l.nonZeros);
    w.field("max_residual_before", l.maxResidualBefore);
    w.key("cg").beginObject().field("converged", l.solve.converged).field("stop_reason", stopReasonName(l.solve.reason));
    w.field("iterations", l.solve.iterations).field("relative_residual", l.solve.relativeResidual);
    w.field("tolerance", l.solve.tolerance).endObject();
    w.key("seconds").beginObject().field("constraints", l.secondsConstraints).field("residual", l.secondsResidual);
    w.field("assembly", l.secondsAssembly).field("solve", l.secondsSolve).endObject();
    w.endObject();
  }
  w.endArray();
  w.field("E0", rep.e0).key("Edelta").beginArray();
  for (double e : rep.eDelta) w.value(e);
  w.endArray();
  const OffsetCorrectionReport& c = rep.correction;
  w.key("offset_correction").beginObject().field("applied", c.applied).field("sigma", c.sigma);
  w.field("points", c.points).field("nonzeros", c.nonZeros).field("mean_before", c.meanBefore);
  w.field("max_before", c.maxBefore).field("cg_iterations", c.solve.iterations);
  w.field("cg_converged", c.solve.converged).field("seconds", c.seconds).endObject();
  w.field("winding_seconds", rep.secondsWinding);
}

void writeSelfCheck(JsonWriter& w, const SelfCheckReport& r, const std::vector<std::string>& meshNames) {
  w.key("self_check").beginObject().field("ok", r.ok()).field("points_checked", r.pointsChecked);
  w.field("point_tolerance", r.pointTolerance).field("min_component", r.minAreaFraction);
  w.field("min_offset_component", r.minOffsetAreaFraction);
  w.key("surfaces").beginArray();
  for (const SurfaceSelfCheck& s : r.surfaces) {
    w.beginObject().field("surface", s.surface).field("file", meshNames[static_cast<std::size_t>(s.surface)]);
    w.field("iso", s.iso).field("components", s.components).field("faces", s.faces).field("area", s.area);
    w.field("issues", s.issues);
    w.key("dropped").beginObject().field("components", s.dropped.components).field("faces", s.dropped.faces);
    w.field("area", s.dropped.area).field("area_fraction", s.dropped.areaFraction).endObject();
    w.endObject();
  }
  w.endArray().key("issues").beginArray();
  for (const ComponentIssue& i : r.issues) {
    w.beginObject().field("surface", i.surface).field("file", meshNames[static_cast<std::size_t>(i.surface)]);
    w.field("iso", i.iso).field("component", i.component).field("why", componentIssueName(i.why));
    w.field("faces", i.faces).field("vertices", i.vertices).field("area", i.area);
    w.field("area_fraction", i.areaFraction);
    w.key("box").beginObject().key("min").beginArray();
    for (int k = 0; k < 3; ++k) w.value(i.box.min()[k]);
    w.endArray().key("max").beginArray();
    for (int k = 0; k < 3; ++k) w.value(i.box.max()[k]);
    w.endArray().endObject();
    w.field("mean_distance", i.meanDistance).field("mean_deviation", i.meanDeviation);
    w.field("nearest_input_point", i.nearestInputPoint).endObject();
  }
  w.endArray().field("seconds", r.seconds).endObject();
}

}  // namespace

void writePipelineReport(std::ostream& out, const PipelineResult& result, const std::string& meshFormat,
                         double writeSeconds) {
  const PipelineReport& report = result.report;
  const FitReport& rep = report.fit;
  const bool separate = report.separate;
  const std::vector<std::string> meshNames = pipelineMeshNames(result, meshFormat);
  const std::vector<std::string> fieldNames = pipelineFieldNames(result);
  JsonWriter w(out);
  w.beginObject().field("input", report.input).field("points", report.read.points);
  w.field("duplicates_merged", report.duplicatesMerged);
  w.field("mode", separate ? "separate" : "duplex").field("side_test", report.sideTest);
  w.key("preprocessing").beginObject();
  w.key("normals");
  if (report.normals) {
    const NormalReport& n = *report.normals;
    w.beginObject().field("method", "PCA + Riemannian MST propagation + enclosed-volume sign");
    w.field("k", n.k).field("graph_k", n.graphK).field("input_had_normals", report.read.normals);
    w.field("components", n.components).field("flipped_components", n.flippedComponents);
    w.field("ambiguous_components", n.ambiguousComponents).field("nested_components", n.nestedComponents);
    w.field("degenerate", n.degenerate).field("non_planar", n.nonPlanar).field("seconds", n.seconds).endObject();
  } else {
    w.null();
  }
  w.key("denoise");
  if (report.denoise) {
    const BilateralReport& b = *report.denoise;
    w.beginObject().field("method", "bilateral point filter (docs/method.md section 9)");
    w.field("sigma_spatial", b.sigmaSpatial).field("sigma_range", b.sigmaRange).field("radius", b.radius);
    w.field("area_sigma", b.areaSigma).field("iterations", b.iterations).field("symmetric_range", b.symmetricRange);
    w.field("mean_neighbors", b.meanNeighbors).field("moved", b.moved);
    w.field("max_displacement", b.maxDisplacement).field("mean_displacement", b.meanDisplacement);
    w.field("seconds", b.seconds).endObject();
  } else {
    w.null();
  }
  w.endObject();
  if (!separate) {
    writeFitReport(w, rep);
  } else {
    w.field("device", rep.device).field("precision", rep.precision).key("offsets").beginArray();
    for (double d : rep.offsets) w.value(d);
    w.endArray();
    w.field("E0", rep.e0).key("Edelta").beginArray();
    for (double e : rep.eDelta) w.value(e);
    w.endArray();
    w.key("fits").beginArray();
    for (std::size_t i = 0; i < report.separateFits.size(); ++i) {
      w.beginObject().field("surface", i == 0 ? std::string("zero") : "offset" + std::to_string(i));
      w.field("delta", i == 0 ? 0.0 : rep.offsets[i - 1]);
      w.field("fitted_points", report.separateFittedPoints[i]);
      writeFitReport(w, report.separateFits[i]);
      w.endObject();
    }
    w.endArray();
  }
  w.key("meshes").beginArray();
  for (std::size_t i = 0; i < result.surfaces.size(); ++i) {
    const PipelineSurface& s = result.surfaces[i];
    w.beginObject().field("file", meshNames[i]).field("iso", s.iso);
    w.field("field", fieldNames[s.field]).key("topology");
    writeTopology(w, s.topology);
    w.endObject();
  }
  w.endArray();
  writeSelfCheck(w, report.selfCheck, meshNames);
  w.key("grid").beginObject().field("nx", report.grid.cells.x()).field("ny", report.grid.cells.y());
  w.field("nz", report.grid.cells.z()).field("cell", report.grid.cellSize().maxCoeff());
  w.field("evaluated_fraction", report.gridStats.evaluatedFraction()).field("box_growths", report.boxGrowths);
  w.field("continued_cells", report.gridStats.continuedCells).field("touches_boundary", report.touchesBoundary);
  w.field("sampler_seconds", report.gridStats.samplerSeconds);
  w.field("extraction_seconds", report.gridStats.extractionSeconds);
  w.endObject();
  w.key("seconds").beginObject().field("read", report.secondsRead).field("hierarchy", rep.secondsHierarchy);
  w.field("fit", rep.secondsTotal).field("polygonize", report.secondsPolygonize).field("write", writeSeconds);
  w.field("total", report.secondsTotal + writeSeconds).endObject();
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  w.field("peak_rss_mib", static_cast<double>(usage.ru_maxrss) / 1024.0);
  w.endObject();
}

}  // namespace duplexfit
