// simplifyMesh: meshoptimizer's simplifier (meshopt_simplify, not the sloppy one) to a triangle budget
// and/or an error bound, with the result's topology checked against the input's and the library's own
// edge collapses as the fallback. Without meshoptimizer in the build (DUPLEXFIT_HAVE_MESHOPTIMIZER
// undefined) every request is a clear error.
#include <algorithm>
#include <array>
#include <utility>
#include <chrono>
#include <cmath>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/mesh_finish.hpp"
#include "surfaces/collapse.hpp"

#ifdef DUPLEXFIT_HAVE_MESHOPTIMIZER
#include <meshoptimizer.h>
#endif

namespace duplexfit {

bool simplificationAvailable() noexcept {
#ifdef DUPLEXFIT_HAVE_MESHOPTIMIZER
  return true;
#else
  return false;
#endif
}

namespace {

bool sameTopology(const MeshTopology& a, const MeshTopology& b) {
  return a.watertight() == b.watertight() && a.manifold() == b.manifold() && a.oriented() == b.oriented() &&
         a.components == b.components && a.eulerCharacteristic == b.eulerCharacteristic &&
         b.degenerateFaces == 0 && b.faces > 0;
}

#ifdef DUPLEXFIT_HAVE_MESHOPTIMIZER
/// The faces given by `indices` (3 per face) with only their vertices, in first-use order, without the
/// pairs (or larger groups) of faces on the same three vertices; `dropped` counts the groups.
Mesh compacted(const Mesh& mesh, const std::vector<unsigned>& indices, std::size_t& dropped) {
  const std::size_t nf = indices.size() / 3;
  std::vector<std::pair<std::array<unsigned, 3>, std::size_t>> keys(nf);
  for (std::size_t f = 0; f < nf; ++f) {
    std::array<unsigned, 3> k = {indices[3 * f], indices[3 * f + 1], indices[3 * f + 2]};
    std::sort(k.begin(), k.end());
    keys[f] = {k, f};
  }
  std::sort(keys.begin(), keys.end());
  std::vector<char> keep(nf, 1);
  dropped = 0;
  for (std::size_t i = 0; i < nf;) {
    std::size_t j = i + 1;
    while (j < nf && keys[j].first == keys[i].first) ++j;
    if (j - i > 1) {
      ++dropped;
      for (std::size_t k = i; k < j; ++k) keep[keys[k].second] = 0;
    }
    i = j;
  }
  std::vector<int> id(static_cast<std::size_t>(mesh.vertices.rows()), -1);
  int next = 0;
  std::size_t kept = 0;
  for (std::size_t f = 0; f < nf; ++f) {
    if (!keep[f]) continue;
    ++kept;
    for (int k = 0; k < 3; ++k) {
      const unsigned v = indices[3 * f + static_cast<std::size_t>(k)];
      if (id[v] < 0) id[v] = next++;
    }
  }
  Mesh m;
  m.vertices.resize(next, 3);
  for (std::size_t v = 0; v < id.size(); ++v) {
    if (id[v] >= 0) m.vertices.row(id[v]) = mesh.vertices.row(static_cast<Eigen::Index>(v));
  }
  m.faces.resize(static_cast<Eigen::Index>(kept), 3);
  Eigen::Index row = 0;
  for (std::size_t f = 0; f < nf; ++f) {
    if (!keep[f]) continue;
    for (int k = 0; k < 3; ++k) m.faces(row, k) = id[indices[3 * f + static_cast<std::size_t>(k)]];
    ++row;
  }
  return m;
}
#endif

}  // namespace

SimplifyResult simplifyMesh(const Mesh& mesh, const SimplifyOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (!(options.maxError >= 0.0) || !std::isfinite(options.maxError)) {
    throw InvalidArgument("simplification: the error bound must be a finite number >= 0");
  }
  SimplifyResult r;
  r.report.facesBefore = static_cast<std::size_t>(mesh.faces.rows());
  r.report.facesAfter = r.report.facesBefore;
  if (options.maxTriangles == 0 && options.maxError == 0.0) {
    r.mesh = mesh;
    return r;
  }
  if (!simplificationAvailable()) {
    throw InvalidArgument("mesh simplification (--max-triangles, --max-error) needs meshoptimizer, and this build "
                          "of duplexfit has none (install libmeshoptimizer-dev and configure again)");
  }
  r.report.applied = true;
  const auto finish = [&](Mesh m) {
    r.mesh = std::move(m);
    r.report.facesAfter = static_cast<std::size_t>(r.mesh.faces.rows());
    r.report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return r;
  };
  if (options.maxTriangles > 0 && r.report.facesBefore <= options.maxTriangles && options.maxError == 0.0) {
    return finish(mesh);  // already within the budget
  }
  const MeshTopology before = analyzeTopology(mesh);
#ifdef DUPLEXFIT_HAVE_MESHOPTIMIZER
  const auto nv = static_cast<std::size_t>(mesh.vertices.rows());
  std::vector<float> positions(3 * nv);
  for (std::size_t v = 0; v < nv; ++v) {
    for (int k = 0; k < 3; ++k) {
      positions[3 * v + static_cast<std::size_t>(k)] = static_cast<float>(mesh.vertices(static_cast<Eigen::Index>(v), k));
    }
  }
  std::vector<unsigned> indices(3 * r.report.facesBefore);
  for (std::size_t i = 0; i < indices.size(); ++i) {
    indices[i] = static_cast<unsigned>(mesh.faces(static_cast<Eigen::Index>(i / 3), static_cast<Eigen::Index>(i % 3)));
  }
  const float scale = meshopt_simplifyScale(positions.data(), nv, 3 * sizeof(float));
  r.report.targetError = options.maxError > 0.0 ? options.maxError / static_cast<double>(scale) : 1.0;
  std::vector<unsigned> out(indices.size());
  float error = 0.0f;
#if MESHOPTIMIZER_VERSION >= 180
  const std::size_t n = meshopt_simplify(out.data(), indices.data(), indices.size(), positions.data(), nv,
                                         3 * sizeof(float), 3 * options.maxTriangles,
                                         static_cast<float>(r.report.targetError), 0, &error);
#else
  const std::size_t n = meshopt_simplify(out.data(), indices.data(), indices.size(), positions.data(), nv,
                                         3 * sizeof(float), 3 * options.maxTriangles,
                                         static_cast<float>(r.report.targetError), &error);
#endif
  out.resize(n);
  Mesh simplified = compacted(mesh, out, r.report.duplicatePairsRemoved);
  if (sameTopology(before, analyzeTopology(simplified))) {
    r.report.resultError = static_cast<double>(error) * static_cast<double>(scale);
    return finish(std::move(simplified));
  }
#endif
  // meshoptimizer changed the topology: the library's own collapses, which check the link condition.
  r.report.fallback = true;
  Mesh collapsed = detail::collapseSimplify(mesh, options.maxTriangles, options.maxError);
  if (sameTopology(before, analyzeTopology(collapsed))) return finish(std::move(collapsed));
  r.report.topologyKept = false;
  return finish(mesh);
}

}  // namespace duplexfit
