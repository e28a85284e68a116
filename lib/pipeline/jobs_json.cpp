// The reports of the jobs in jobs.hpp: the --json documents of measure, check, denoise, normals, section
// and slice (slices.json) with the keys the CLI has always written (add keys, never rename or remove one),
// and the text tables of measure and check. nlohmann::ordered_json keeps the keys in this order.
#include <algorithm>
#include <iomanip>
#include <limits>
#include <nlohmann/json.hpp>
#include <ostream>
#include <sstream>

#include "duplexfit/jobs.hpp"

namespace duplexfit {

namespace {

using Json = nlohmann::ordered_json;

void print(std::ostream& out, const Json& j) { out << j.dump(2, ' ', false, Json::error_handler_t::replace) << "\n"; }

std::string num(double v, int precision = 6) {
  std::ostringstream s;
  s << std::setprecision(precision) << v;
  return s.str();
}

std::string percent(double v, double of) {
  if (!(of > 0.0)) return "-";
  std::ostringstream s;
  s << std::fixed << std::setprecision(4) << 100.0 * v / of << " %";
  return s.str();
}

Json vec(const Eigen::Vector3d& p) { return Json::array({p.x(), p.y(), p.z()}); }

Json meshJson(const MeasuredMesh& m) {
  return Json{{"file", m.path},
              {"vertices", m.validation.vertices},
              {"faces", m.validation.faces},
              {"degenerate_faces", m.validation.degenerateFaces()}};
}

Json statsJson(const SampleStats& s, double relativeTo = 0.0) {
  Json j{{"samples", s.samples}, {"min", s.min}, {"max", s.max}, {"mean", s.mean}, {"rms", s.rms}, {"p99", s.p99}};
  if (relativeTo > 0.0) {
    j["max_rel"] = s.max / relativeTo;
    j["mean_rel"] = s.mean / relativeTo;
    j["rms_rel"] = s.rms / relativeTo;
  }
  j["max_at"] = vec(s.maxAt);
  j["max_closest"] = vec(s.maxClosest);
  return j;
}

std::string point(const Eigen::Vector3d& p) { return "(" + num(p.x()) + ", " + num(p.y()) + ", " + num(p.z()) + ")"; }

void statsRow(std::ostream& out, const char* name, const SampleStats& s, double diagonal) {
  out << std::left << std::setw(20) << name << std::right << std::setw(14) << num(s.max) << std::setw(14)
      << num(s.mean) << std::setw(14) << num(s.rms) << std::setw(14) << num(s.p99) << std::setw(12) << s.samples
      << "\n";
  if (diagonal > 0.0) {
    out << std::left << std::setw(20) << "  / diagonal of B" << std::right << std::setw(14) << percent(s.max, diagonal)
        << std::setw(14) << percent(s.mean, diagonal) << std::setw(14) << percent(s.rms, diagonal) << std::setw(14)
        << percent(s.p99, diagonal) << "\n";
  }
}

void header(std::ostream& out) {
  out << std::left << std::setw(20) << "" << std::right << std::setw(14) << "max" << std::setw(14) << "mean"
      << std::setw(14) << "RMS" << std::setw(14) << "p99" << std::setw(12) << "samples" << "\n";
}

}  // namespace

// ---- measure and check -------------------------------------------------------------------------------

void writeDistanceJson(std::ostream& out, const DistanceJobResult& result) {
  const DistanceReport& r = result.report;
  const double diag = r.diagonalB;
  print(out, Json{{"mode", "distance"},
                  {"a", meshJson(result.a)},
                  {"b", meshJson(result.b)},
                  {"samples_per_face", result.options.samplesPerFace},
                  {"seed", result.options.seed},
                  {"diagonal_b", diag},
                  {"forward", statsJson(r.forward, diag)},
                  {"backward", statsJson(r.backward, diag)},
                  {"hausdorff", r.hausdorff},
                  {"hausdorff_rel", diag > 0.0 ? r.hausdorff / diag : 0.0},
                  {"seconds", result.seconds}});
}

void writeOffsetJson(std::ostream& out, const OffsetJobResult& result) {
  const OffsetReport& r = result.report;
  Json components = Json::array();
  for (std::size_t i = 0; i < r.components.size() && i < 50; ++i) {
    const OffsetReport::Component& c = r.components[i];
    components.push_back(Json{{"faces", c.faces},
                              {"mean_distance", c.meanDistance},
                              {"mean_deviation", c.meanDeviation},
                              {"max_deviation", c.maxDeviation},
                              {"off_offset", c.offOffset}});
  }
  print(out, Json{{"mode", "offset"},
                  {"offset", meshJson(result.offset)},
                  {"surface", meshJson(result.surface)},
                  {"delta", result.delta},
                  {"samples_per_face", result.options.samplesPerFace},
                  {"seed", result.options.seed},
                  {"samples", r.samples},
                  {"distance", statsJson(r.distance)},
                  {"deviation", statsJson(r.deviation)},
                  {"relative_distance", statsJson(r.relativeDistance)},
                  {"relative_deviation", statsJson(r.relativeDeviation)},
                  {"wrong_side", r.wrongSide},
                  {"wrong_side_share", r.wrongSideShare},
                  {"components", r.components.size()},
                  {"off_offset_components", r.offOffsetComponents},
                  {"component_list", std::move(components)},
                  {"seconds", result.seconds}});
}

void writeCheckJson(std::ostream& out, const CheckJobResult& result) {
  const MeshCheck& c = result.check;
  const MeshTopology& t = c.topology;
  Json pairs = Json::array();
  for (const auto& p : c.pairs) pairs.push_back(Json::array({p.first, p.second}));
  print(out, Json{{"file", result.mesh.path},
                  {"vertices", t.vertices},
                  {"faces", t.faces},
                  {"edges", t.edges},
                  {"valid", c.valid()},
                  {"watertight", c.watertight},
                  {"manifold", c.manifold},
                  {"oriented", c.oriented},
                  {"outward", c.outward},
                  {"signed_volume", c.signedVolume},
                  {"area", c.area},
                  {"components", t.components},
                  {"euler_characteristic", t.eulerCharacteristic},
                  {"genus", c.genusKnown ? Json(c.genus) : Json()},
                  {"boundary_edges", t.boundaryEdges},
                  {"boundary_loops", c.boundaryLoops},
                  {"non_manifold_edges", t.nonManifoldEdges},
                  {"non_manifold_vertices", t.nonManifoldVertices},
                  {"inconsistent_edges", t.inconsistentEdges},
                  {"degenerate_faces", c.validation.degenerateFaces()},
                  {"repeated_index_faces", c.validation.repeatedIndexFaces},
                  {"zero_area_faces", c.validation.zeroAreaFaces},
                  // corners rounded to float32 (STL, binary PLY) coincide or have zero area: always invalid
                  {"float32_degenerate_faces", c.quality.float32DegenerateFaces},
                  {"first_float32_degenerate_face", c.quality.firstFloat32DegenerateFace},
                  {"sliver_angle", c.quality.sliverAngle},
                  {"slivers", c.quality.slivers},
                  {"too_many_slivers", c.tooManySlivers},
                  {"min_angle", c.quality.minAngle},
                  {"worst_face", c.quality.worstFace},
                  {"shortest_edge", c.quality.shortestEdge},
                  {"min_angle_histogram",
                   {{"below_1", c.quality.below1}, {"below_5", c.quality.below5}, {"below_10", c.quality.below10}}},
                  {"self_intersections_checked", c.selfIntersectionsChecked},
                  {"self_intersections", c.selfIntersectionsChecked ? Json(c.selfIntersections) : Json()},
                  // false: the per-face work bound was reached and self_intersections is a lower bound
                  {"self_intersections_complete", c.selfIntersectionsChecked && c.selfIntersectionsComplete},
                  {"intersecting_pairs", std::move(pairs)},
                  {"seconds", result.seconds}});
}

void writeDistanceText(std::ostream& out, const DistanceJobResult& result) {
  const DistanceReport& r = result.report;
  const MeasuredMesh &a = result.a, &b = result.b;
  const double diag = r.diagonalB;
  out << "A  " << a.path << " (" << a.validation.vertices << " vertices, " << a.validation.faces << " faces)\n"
      << "B  " << b.path << " (" << b.validation.vertices << " vertices, " << b.validation.faces
      << " faces, bounding-box diagonal " << num(diag) << ")\n"
      << "sampling: " << num(result.options.samplesPerFace) << " per face + vertices, seed " << result.options.seed
      << "\n\n";
  header(out);
  statsRow(out, "forward  A -> B", r.forward, diag);
  statsRow(out, "backward B -> A", r.backward, diag);
  out << "\nHausdorff (symmetric)  " << num(r.hausdorff) << " (" << percent(r.hausdorff, diag)
      << " of the diagonal of B)\n";
  const SampleStats& worst = r.forward.max >= r.backward.max ? r.forward : r.backward;
  out << "attained " << (r.forward.max >= r.backward.max ? "forward" : "backward") << " at " << point(worst.maxAt)
      << ", closest point " << point(worst.maxClosest) << "\n";
}

void writeOffsetText(std::ostream& out, const OffsetJobResult& result) {
  const OffsetReport& r = result.report;
  const MeasuredMesh &o = result.offset, &s = result.surface;
  const double delta = result.delta;
  out << "offset   " << o.path << " (" << o.validation.vertices << " vertices, " << o.validation.faces << " faces)\n"
      << "surface  " << s.path << " (" << s.validation.vertices << " vertices, " << s.validation.faces
      << " faces)\n"
      << "delta    " << num(delta) << (delta > 0 ? " (inward)" : " (outward)") << ", " << r.samples << " samples ("
      << num(result.options.samplesPerFace) << " per face + vertices, seed " << result.options.seed << ")\n\n";
  header(out);
  statsRow(out, "dist(O, S)", r.distance, 0.0);
  statsRow(out, "|dist - |delta||", r.deviation, 0.0);
  statsRow(out, "dist / |delta|", r.relativeDistance, 0.0);
  statsRow(out, "deviation / |delta|", r.relativeDeviation, 0.0);
  out << "\nwrong side of S  " << r.wrongSide << " samples ("
      << percent(static_cast<double>(r.wrongSide), static_cast<double>(r.samples)) << ")\n"
      << "largest deviation at " << point(r.deviation.maxAt) << ", closest on S " << point(r.deviation.maxClosest)
      << "\n";
  std::size_t small = 0;
  for (std::size_t i = 1; i < r.components.size(); ++i) small += r.components[i].faces < 100 ? 1 : 0;
  out << "components       " << r.components.size() << " (" << small << " of them under 100 faces), "
      << r.offOffsetComponents << " not on the offset (mean |dist - |delta|| > |delta|/2)\n";
}

void writeCheckText(std::ostream& out, const CheckJobResult& result) {
  const MeshCheck& c = result.check;
  const MeshTopology& t = c.topology;
  auto yes = [](bool b) { return b ? "yes" : "no"; };
  out << "mesh                   " << result.mesh.path << "\n"
      << "vertices/edges/faces   " << t.vertices << " / " << t.edges << " / " << t.faces << "\n"
      << "watertight             " << yes(c.watertight) << " (" << t.boundaryEdges << " boundary edges in "
      << c.boundaryLoops << " loops)\n"
      << "2-manifold             " << yes(c.manifold) << " (" << t.nonManifoldEdges << " non-manifold edges, "
      << t.nonManifoldVertices << " non-manifold vertices)\n"
      << "consistently oriented  " << yes(c.oriented) << " (" << t.inconsistentEdges << " inconsistent edges)\n"
      << "outward                " << yes(c.outward) << " (signed volume " << num(c.signedVolume) << ", area "
      << num(c.area) << ")\n"
      << "components             " << t.components << "\n"
      << "Euler characteristic   " << t.eulerCharacteristic << "\n"
      << "genus                  " << (c.genusKnown ? std::to_string(c.genus) : std::string("-")) << "\n"
      << "degenerate triangles   " << c.validation.degenerateFaces() << " (" << c.validation.repeatedIndexFaces
      << " repeated index, " << c.validation.zeroAreaFaces << " zero area)\n"
      << "float32-degenerate     " << c.quality.float32DegenerateFaces
      << " (corners rounded to float32 coincide or have zero area)\n"
      << "slivers                " << c.quality.slivers << " below " << num(c.quality.sliverAngle) << " deg"
      << (c.tooManySlivers ? " (too many)" : "") << "; min angle " << num(c.quality.minAngle) << " deg (face "
      << c.quality.worstFace << "); below 1/5/10 deg: " << c.quality.below1 << " / " << c.quality.below5 << " / "
      << c.quality.below10 << "\n"
      << "self-intersections     "
      << (!c.selfIntersectionsChecked ? std::string("not checked")
          : c.selfIntersectionsComplete
              ? std::to_string(c.selfIntersections) + " triangle pairs"
              : "at least " + std::to_string(c.selfIntersections) +
                    " triangle pairs (the search stopped at its work bound, CheckOptions::candidatePairBudget)")
      << "\n";
  if (!c.pairs.empty()) {
    out << "  first pairs:";
    for (const auto& p : c.pairs) out << " (" << p.first << ", " << p.second << ")";
    out << "\n";
  }
  out << "verdict                " << (c.valid() ? "valid closed oriented manifold" : "not valid") << "\n";
}

// ---- denoise and normals -------------------------------------------------------------------------------

void writeDenoiseJson(std::ostream& out, const DenoiseJobResult& result, const std::string& outputPath,
                      double writeSeconds) {
  const BilateralReport& rep = result.report;
  const CloudJobInfo& info = result.info;
  print(out, Json{{"command", "denoise"},
                  {"input", info.input},
                  {"output", outputPath},
                  {"points", rep.points},
                  {"device", rep.device},
                  {"device_name", info.deviceName},
                  {"precision", precisionName(rep.precision)},
                  {"sigma_spatial", rep.sigmaSpatial},
                  {"sigma_range", rep.sigmaRange},
                  {"radius", rep.radius},
                  {"area_sigma", rep.areaSigma},
                  {"levels", rep.levels},
                  {"r_ave", rep.rAve},
                  {"iterations", rep.iterations},
                  {"symmetric_range", rep.symmetricRange},
                  {"normals_reestimated", rep.normalsReestimated},
                  {"mean_neighbors", rep.meanNeighbors},
                  {"isolated", rep.isolated},
                  {"moved", rep.moved},
                  {"max_displacement", rep.maxDisplacement},
                  {"mean_displacement", rep.meanDisplacement},
                  {"seconds",
                   {{"kernel_build", info.secondsKernelBuild},
                    {"read", info.secondsRead},
                    {"neighbors", rep.neighborSeconds},
                    {"filter", rep.filterSeconds},
                    {"denoise", rep.seconds},
                    {"write", writeSeconds},
                    {"total", info.secondsTotal + writeSeconds}}}});
}

void writeNormalsJson(std::ostream& out, const NormalsJobResult& result, const std::string& outputPath,
                      double writeSeconds) {
  const NormalReport& rep = result.report;
  const CloudJobInfo& info = result.info;
  Json summary{{"command", "normals"},
               {"input", info.input},
               {"output", outputPath},
               {"points", result.points.size()},
               {"input_had_normals", info.inputHadNormals},
               {"kept_existing", result.keptExisting},
               {"device", info.deviceSpec},
               {"device_name", info.deviceName},
               {"precision", precisionName(info.precision)},
               {"k", rep.k},
               {"graph_k", rep.graphK},
               {"duplicates", rep.duplicates},
               {"components", rep.components},
               {"ambiguous_components", rep.ambiguousComponents},
               {"flipped_components", rep.flippedComponents},
               {"nested_components", rep.nestedComponents},
               {"flipped", rep.flipped},
               {"degenerate", rep.degenerate},
               {"non_planar", rep.nonPlanar},
               {"min_volume_ratio", rep.minVolumeRatio}};
  if (result.agreeingWithInput >= 0.0) summary["agree_with_input_normals"] = result.agreeingWithInput;
  summary["seconds"] = Json{{"kernel_build", info.secondsKernelBuild}, {"read", info.secondsRead},
                            {"neighbors", rep.neighborSeconds},        {"pca", rep.pcaSeconds},
                            {"orient", rep.orientSeconds},             {"normals", rep.seconds},
                            {"write", writeSeconds},                   {"total", info.secondsTotal + writeSeconds}};
  print(out, summary);
}

// ---- section -------------------------------------------------------------------------------------------

void writeSectionJson(std::ostream& out, const SectionJobResult& result, const std::string& fieldPath) {
  Json sections = Json::array();
  for (std::size_t i = 0; i < result.sections.size(); ++i) {
    const SectionResult& r = result.sections[i];
    Json j{{"file", result.files[i]},
           {"plane", r.plane.toString()},
           {"width", r.image.width},
           {"height", r.image.height},
           {"pixel_size", r.pixelSize},
           {"axes", Json::array({sectionAxisName(r.plane.rightAxis()), sectionAxisName(r.plane.upAxis())})},
           {"rectangle", Json::array({r.rectangle.min().x(), r.rectangle.min().y(), r.rectangle.max().x(),
                                      r.rectangle.max().y()})},
           {"value_min", r.minValue},
           {"value_max", r.maxValue},
           {"range", r.range}};
    if (result.points) {
      j["band"] = r.band;
      j["points_drawn"] = r.pointsDrawn;
    }
    j["seconds"] = r.seconds;
    sections.push_back(std::move(j));
  }
  print(out, Json{{"field", fieldPath},
                  {"device", result.deviceSpec},
                  {"device_name", result.deviceName},
                  {"precision", precisionName(result.precision)},
                  {"files", result.files},
                  {"levels", result.sections.empty() ? std::vector<double>() : result.sections.front().levels},
                  {"sections", std::move(sections)},
                  {"setup_seconds", result.secondsSetup},
                  {"total_seconds", result.secondsTotal}});
  out << "\n";
}

// ---- slice ---------------------------------------------------------------------------------------------

SliceStats sliceStats(const SliceResult& result) {
  SliceStats s;
  double tMin = std::numeric_limits<double>::infinity(), tSum = 0.0;
  for (const SliceLayer& l : result.layers) {
    tMin = std::min(tMin, l.thickness);
    s.thicknessMax = std::max(s.thicknessMax, l.thickness);
    tSum += l.thickness;
    s.loops += l.loops.size();
  }
  const std::size_t n = result.layers.size();
  s.thicknessMean = n > 0 ? tSum / static_cast<double>(n) : 0.0;
  s.thicknessMin = n == 0 ? 0.0 : tMin;
  return s;
}

void writeSliceJson(std::ostream& out, const SliceJobResult& job, const std::vector<double>& maskArea,
                    double writeSeconds, const Sl1Summary* sl1) {
  const SliceResult& result = job.slices;  // the slicer's parameters, model units
  const SliceResult& placed = job.placed;  // the layers in output coordinates
  const SliceStats stats = sliceStats(placed);
  const std::size_t n = placed.layers.size();
  Json heights = Json::array(), areas = Json::array(), loopsPerLayer = Json::array(), layers = Json::array();
  for (const SliceLayer& l : placed.layers) {
    heights.push_back(l.height);
    areas.push_back(l.area);
    loopsPerLayer.push_back(l.loops.size());
  }
  for (std::size_t i = 0; i < n; ++i) {
    const SliceLayer& l = placed.layers[i];
    std::size_t outer = 0;
    for (const SliceLoop& p : l.loops) outer += p.outer() ? 1 : 0;
    Json j{{"index", i + 1},
           {"height", l.height},
           {"bottom", l.height},
           {"top", l.height + l.thickness},
           {"thickness", l.thickness},
           {"raw_thickness", l.rawThickness},
           {"area", l.area},
           {"loops", l.loops.size()},
           {"outer_loops", outer},
           {"holes", l.loops.size() - outer},
           {"vertices", l.vertexCount()}};
    if (i < maskArea.size()) j["mask_area"] = maskArea[i];
    if (l.touchesBoundary) j["touches_border"] = true;
    layers.push_back(std::move(j));
  }
  const SlicePlacement& place = job.placement;
  const std::string axes = "xyz", u(1, axes[(result.axis + 1) % 3]), v(1, axes[(result.axis + 2) % 3]);
  const Eigen::Vector3d& t = place.translation;
  Json placement{{"place", slicePlaceName(place.place)},
                 {"scale", place.scale},
                 {"units", job.options.unitsName},
                 {"units_mm", job.options.units},
                 {"translation", vec(t)},
                 {"model_axes", {u, v, std::string(1, axes[result.axis])}},
                 {"map", "output = scale * model + translation, output (x, y, z) = model (model_axes)"},
                 {"plate", {place.plate.sizes().x(), place.plate.sizes().y()}},
                 {"plate_min", {place.plate.min().x(), place.plate.min().y()}},
                 {"plate_given", place.plateGiven},
                 {"part_min", vec(place.part.min())},
                 {"part_max", vec(place.part.max())},
                 {"lowest_model", place.lowestModel}};
  const double sliceSeconds = job.secondsSlice;
  Json summary{
      {"input", job.input},
      {"device", job.deviceSpec},
      {"mode", sliceModeName(result.mode)},
      {"axis", std::string(1, "xyz"[result.axis])},
      {"adaptive", result.adaptive},
      {"cusp_rule", cuspRuleName(result.rule)},
      {"cusp", result.cusp},
      {"min_layer", result.minLayer},
      {"max_layer", result.maxLayer},
      {"uniform_layer", result.layer},
      {"grid", result.grid},
      {"units_mm", job.options.units},
      {"levels", result.levels},
      {"start", result.start},
      {"end", result.end},
      {"layer_count", n},
      {"thickness", {{"min", stats.thicknessMin}, {"mean", stats.thicknessMean}, {"max", stats.thicknessMax}}},
      {"loops", stats.loops},
      {"vertices", result.vertices},
      {"samples", result.samples},
      {"refine_evaluations", result.refineEvaluations},
      {"layers_touching_border", job.layersTouchingBorder},
      {"heights", std::move(heights)},
      {"areas", std::move(areas)},
      {"loops_per_layer", std::move(loopsPerLayer)},
      {"layers", std::move(layers)},
      {"seconds", {{"slice", sliceSeconds}, {"write", writeSeconds}, {"total", job.secondsTotal + writeSeconds}}},
      {"layers_per_second", sliceSeconds > 0 ? static_cast<double>(n) / sliceSeconds : 0.0},
      {"vertices_per_second", sliceSeconds > 0 ? static_cast<double>(result.vertices) / sliceSeconds : 0.0},
      {"placement", std::move(placement)}};
  if (!job.options.drainHoles.empty()) {
    Json holes = Json::array();
    for (const DrainHole& h : job.options.drainHoles) {
      holes.push_back(Json{{"point", vec(h.point)}, {"radius", h.radius}});
    }
    summary["drain_holes"] = std::move(holes);  // only with holes: the layers are then of min(f, delta - f, holes)
  }
  if (job.options.maskPixel > 0.0) {
    const SliceMaskInfo m = sliceMaskInfo(job);
    summary["masks"] = Json{{"pixel", m.pixel},
                            {"width_px", m.width},
                            {"height_px", m.height},
                            {"origin", {m.origin.x(), m.origin.y()}},
                            {"origin_is", "the outer corner of pixel (0, 0): columns go +x, rows go -y"},
                            {"area_min", {m.area.min().x(), m.area.min().y()}},
                            {"area_max", {m.area.max().x(), m.area.max().y()}},
                            {"pixels_per_metre", m.pixelsPerMetre},
                            {"dpi", m.dpi}};
  }
  if (sl1 != nullptr) {
    const Sl1Options& o = job.options.sl1Options;
    const Sl1Printer& p = o.printer;
    summary["sl1"] = Json{{"file", job.options.sl1},
                          {"job_dir", sl1->jobName},
                          {"layers", sl1->layers},
                          {"layer_height", sl1->layerHeight},
                          {"pixel", sl1->pixel},
                          {"image_px", {sl1->imageWidth, sl1->imageHeight}},
                          {"display", {p.displayWidth, p.displayHeight}},
                          {"display_px", {p.pixelsX, p.pixelsY}},
                          {"orientation", sl1OrientationName(p.orientation)},
                          {"mirror", {p.mirrorX, p.mirrorY}},
                          {"printer_model", p.model},
                          {"exposure", o.exposure},
                          {"initial_exposure", o.initialExposure},
                          {"fade_layers", o.fadeLayers},
                          {"num_fast", sl1->numFast},
                          {"num_slow", sl1->numSlow},
                          {"print_time", sl1->printTime},
                          {"used_material_ml", sl1->usedMaterial},
                          {"exposed_area", sl1->exposedArea},
                          {"entries", sl1->entries.size()},
                          {"bytes", sl1->bytes}};
  }
  print(out, summary);
}

}  // namespace duplexfit
