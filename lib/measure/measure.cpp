// Mesh validation, Metro sampling (stratified area-uniform face samples from a counter-based random
// generator, so results do not depend on the thread count), two-sided distances and offset accuracy
// with the inside/outside decision by angle-weighted pseudo-normals (Bærentzen & Aanæs 2005).
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/measure.hpp"
#include "measure/geometry.hpp"
#include "measure/parallel_errors.hpp"

namespace duplexfit {

namespace {

/// validateMesh's bound on |coordinate|: the measurements take products of up to four coordinate
/// differences (squared areas), which stay finite below it.
constexpr double kMaxCoordinate = 1e64;

const char* axisName(int k) { return k == 0 ? "x" : (k == 1 ? "y" : "z"); }

/// |(b − a) × (c − a)| ≤ 1e-12 · (longest edge)².
bool zeroArea(const double* a, const double* b, const double* c) {
  double ab[3], ac[3], bc[3], n[3];
  geom::sub(b, a, ab);
  geom::sub(c, a, ac);
  geom::sub(c, b, bc);
  geom::cross(ab, ac, n);
  const double longest2 = std::max({geom::norm2(ab), geom::norm2(ac), geom::norm2(bc)});
  return std::sqrt(geom::norm2(n)) <= 1e-12 * longest2;
}

// Counter-based random numbers: splitmix64's finaliser over (seed, face, counter).
std::uint64_t mix(std::uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}
double uniform(std::uint64_t seed, std::uint64_t face, std::uint64_t counter) {
  const std::uint64_t h = mix(mix(seed ^ mix(face)) + counter);
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

const double* vertexPtr(const Mesh& m, std::int32_t v) {
  return m.vertices.data() + 3 * static_cast<std::size_t>(v);
}

double bboxDiagonal(const Mesh& m) {
  if (m.vertices.rows() == 0) return 0.0;
  return (m.vertices.colwise().maxCoeff() - m.vertices.colwise().minCoeff()).norm();
}

void checkOptions(const MeasureOptions& options) {
  if (!(options.samplesPerFace > 0.0) || !std::isfinite(options.samplesPerFace)) {
    throw InvalidArgument("samples per face must be a positive number (got " +
                          std::to_string(options.samplesPerFace) + ")");
  }
  if (options.samplesPerFace > 1e6) {
    throw InvalidArgument("samples per face must be at most 1e6 (got " + std::to_string(options.samplesPerFace) + ")");
  }
}

/// Summary of `values` (reordered: p99 uses nth_element). argmax is written to *argmax.
SampleStats summarize(std::vector<double>& values, std::size_t* argmax) {
  SampleStats s;
  s.samples = values.size();
  *argmax = 0;
  if (values.empty()) return s;
  double sum = 0.0, sum2 = 0.0;
  s.min = s.max = values[0];
  for (std::size_t i = 0; i < values.size(); ++i) {
    const double v = values[i];
    sum += v;
    sum2 += v * v;
    if (v > s.max) {
      s.max = v;
      *argmax = i;
    }
    s.min = std::min(s.min, v);
  }
  const auto n = static_cast<double>(values.size());
  s.mean = sum / n;
  s.rms = std::sqrt(sum2 / n);
  const auto rank = static_cast<std::size_t>(std::ceil(0.99 * n));
  const std::size_t k = rank == 0 ? 0 : rank - 1;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  s.p99 = values[k];
  return s;
}

SampleStats scaled(SampleStats s, double factor) {
  s.min *= factor;
  s.max *= factor;
  s.mean *= factor;
  s.rms *= factor;
  s.p99 *= factor;
  return s;
}

/// Samples measured between two polls of the interrupter.
constexpr Eigen::Index kPollChunk = Eigen::Index{1} << 16;

/// Polls `interrupter` (may be null) with `percent`; throws Cancelled naming `what` when it says stop.
void poll(Interrupter* interrupter, double percent, const char* what) {
  if (interrupter != nullptr && interrupter->wasInterrupted(static_cast<int>(std::clamp(percent, 0.0, 100.0)))) {
    throw Cancelled(std::string(what) + " cancelled");
  }
}

/// One-sided distances from samples to a tree; the polls span percents [p0, p1].
SampleStats oneSided(const MeshSamples& samples, const TriangleBvh& tree, Interrupter* interrupter, double p0,
                     double p1) {
  const Eigen::Index n = samples.points.rows();
  std::vector<double> values(static_cast<std::size_t>(n));
  for (Eigen::Index begin = 0; begin < n; begin += kPollChunk) {
    const Eigen::Index count = std::min(kPollChunk, n - begin);
    const Eigen::VectorXd d = tree.distances(samples.points.middleRows(begin, count));
    std::copy(d.data(), d.data() + count, values.begin() + static_cast<std::ptrdiff_t>(begin));
    poll(interrupter, p0 + (p1 - p0) * static_cast<double>(begin + count) / static_cast<double>(n), "measure");
  }
  std::size_t argmax = 0;
  SampleStats s = summarize(values, &argmax);
  if (s.samples > 0) {
    s.maxAt = samples.points.row(static_cast<Eigen::Index>(argmax)).transpose();
    s.maxClosest = tree.closest(s.maxAt).point;
  }
  return s;
}

/// Angle-weighted pseudo-normals of a mesh: unit face normals, vertex normals, and edge normals on
/// demand (the sum over the faces around the edge, found through the vertex → face lists).
class PseudoNormals {
 public:
  explicit PseudoNormals(const Mesh& m) : mesh_(m) {
    const auto nf = static_cast<std::size_t>(m.faces.rows());
    const auto nv = static_cast<std::size_t>(m.vertices.rows());
    faceNormals_.assign(3 * nf, 0.0);
    vertexNormals_.assign(3 * nv, 0.0);
    start_.assign(nv + 1, 0);
    const std::int32_t* f = m.faces.data();
    for (std::size_t i = 0; i < 3 * nf; ++i) ++start_[static_cast<std::size_t>(f[i]) + 1];
    for (std::size_t v = 0; v < nv; ++v) start_[v + 1] += start_[v];
    incident_.resize(3 * nf);
    std::vector<std::size_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < nf; ++i) {
      for (std::size_t k = 0; k < 3; ++k) {
        incident_[fill[static_cast<std::size_t>(f[3 * i + k])]++] = static_cast<std::uint32_t>(i);
      }
      const double* a = vertexPtr(m, f[3 * i]);
      const double* b = vertexPtr(m, f[3 * i + 1]);
      const double* c = vertexPtr(m, f[3 * i + 2]);
      double ab[3], ac[3], n[3];
      geom::sub(b, a, ab);
      geom::sub(c, a, ac);
      geom::cross(ab, ac, n);
      const double len = std::sqrt(geom::norm2(n));
      if (!(len > 0.0)) continue;
      for (int k = 0; k < 3; ++k) faceNormals_[3 * i + static_cast<std::size_t>(k)] = n[k] / len;
      const double* corner[3] = {a, b, c};
      for (std::size_t k = 0; k < 3; ++k) {
        double e1[3], e2[3];
        geom::sub(corner[(k + 1) % 3], corner[k], e1);
        geom::sub(corner[(k + 2) % 3], corner[k], e2);
        const double l1 = std::sqrt(geom::norm2(e1)), l2 = std::sqrt(geom::norm2(e2));
        if (!(l1 > 0.0 && l2 > 0.0)) continue;
        const double angle = std::acos(std::clamp(geom::dot(e1, e2) / (l1 * l2), -1.0, 1.0));
        const auto v = static_cast<std::size_t>(f[3 * i + k]);
        for (std::size_t c2 = 0; c2 < 3; ++c2) vertexNormals_[3 * v + c2] += angle * faceNormals_[3 * i + c2];
      }
    }
  }

  /// The pseudo-normal (not normalised) of the closest feature.
  Eigen::Vector3d at(const ClosestPoint& cp) const {
    const auto face = static_cast<std::size_t>(cp.face);
    const std::int32_t* f = mesh_.faces.data() + 3 * face;
    if (cp.feature == TriangleFeature::Face) return vec(faceNormals_, face);
    if (cp.feature == TriangleFeature::Vertex) {
      return vec(vertexNormals_, static_cast<std::size_t>(f[cp.local]));
    }
    const std::int32_t i = f[cp.local], j = f[(cp.local + 1) % 3];
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (std::size_t k = start_[static_cast<std::size_t>(i)]; k < start_[static_cast<std::size_t>(i) + 1]; ++k) {
      const std::size_t g = incident_[k];
      const std::int32_t* t = mesh_.faces.data() + 3 * g;
      if (t[0] == j || t[1] == j || t[2] == j) sum += vec(faceNormals_, g);
    }
    return sum;
  }

 private:
  static Eigen::Vector3d vec(const std::vector<double>& a, std::size_t i) {
    return Eigen::Vector3d(a[3 * i], a[3 * i + 1], a[3 * i + 2]);
  }
  const Mesh& mesh_;
  std::vector<double> faceNormals_, vertexNormals_;
  std::vector<std::size_t> start_;
  std::vector<std::uint32_t> incident_;
};

}  // namespace

MeshValidation validateMesh(const Mesh& mesh, const std::string& source) {
  MeshValidation r;
  const Eigen::Index nv = mesh.vertices.rows();
  const Eigen::Index nf = mesh.faces.rows();
  r.vertices = static_cast<std::size_t>(nv);
  r.faces = static_cast<std::size_t>(nf);
  if (nf == 0) {
    throw InvalidArgument(source + ": mesh has no faces (" + std::to_string(nv) + " vertices)");
  }
  const double* v = mesh.vertices.data();
  for (Eigen::Index i = 0; i < nv; ++i) {
    for (int k = 0; k < 3; ++k) {
      const double x = v[3 * i + k];
      if (!std::isfinite(x)) {
        throw InvalidArgument(source + ": vertex " + std::to_string(i) + ": coordinate " + axisName(k) +
                              (std::isnan(x) ? " is NaN" : " is infinite"));
      }
      if (std::abs(x) > kMaxCoordinate) {
        std::ostringstream value;
        value << std::setprecision(6) << x;
        throw InvalidArgument(source + ": vertex " + std::to_string(i) + ": coordinate " + axisName(k) + " = " +
                              value.str() + " is too large (|coordinate| > 1e64: areas and squared distances "
                              "would overflow)");
      }
    }
  }
  const std::int32_t* f = mesh.faces.data();
  for (Eigen::Index i = 0; i < nf; ++i) {
    const std::int32_t* t = f + 3 * i;
    for (int k = 0; k < 3; ++k) {
      if (t[k] < 0 || t[k] >= nv) {
        throw InvalidArgument(source + ": face " + std::to_string(i) + ": index " + std::to_string(t[k]) +
                              " out of range (mesh has " + std::to_string(nv) + " vertices)");
      }
    }
    bool degenerate = false;
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
      ++r.repeatedIndexFaces;
      degenerate = true;
    } else if (zeroArea(vertexPtr(mesh, t[0]), vertexPtr(mesh, t[1]), vertexPtr(mesh, t[2]))) {
      ++r.zeroAreaFaces;
      degenerate = true;
    }
    if (degenerate && r.firstDegenerateFace < 0) r.firstDegenerateFace = i;
  }
  return r;
}

MeshSamples sampleMesh(const Mesh& mesh, const MeasureOptions& options) {
  checkOptions(options);
  validateMesh(mesh, "sampled mesh");
  const auto nf = static_cast<std::size_t>(mesh.faces.rows());
  const auto nv = static_cast<std::size_t>(mesh.vertices.rows());
  const std::int32_t* f = mesh.faces.data();

  std::vector<double> area(nf);
  for (std::size_t i = 0; i < nf; ++i) {
    double ab[3], ac[3], n[3];
    const double* a = vertexPtr(mesh, f[3 * i]);
    geom::sub(vertexPtr(mesh, f[3 * i + 1]), a, ab);
    geom::sub(vertexPtr(mesh, f[3 * i + 2]), a, ac);
    geom::cross(ab, ac, n);
    area[i] = 0.5 * std::sqrt(geom::norm2(n));
  }
  double total = 0.0;
  for (std::size_t i = 0; i < nf; ++i) {
    // validateMesh bounds the coordinates, so this cannot happen; it guards the casts below all the same.
    if (!std::isfinite(area[i])) {
      throw InvalidArgument("sampling: face " + std::to_string(i) + " has a non-finite area (coordinates too large)");
    }
    total += area[i];
  }
  if (!std::isfinite(total)) throw InvalidArgument("sampling: the total area overflows (coordinates too large)");
  const double wanted = std::ceil(options.samplesPerFace * static_cast<double>(nf));
  if (wanted > 2e9) {
    throw InvalidArgument("sampling: " + std::to_string(options.samplesPerFace) + " samples per face on " +
                          std::to_string(nf) + " faces is more than 2e9 samples");
  }
  // Stratified counts: expected wanted·aᵢ/A each (uniform over the faces when the area is zero).
  std::vector<std::size_t> offset(nf + 1, 0);
  for (std::size_t i = 0; i < nf; ++i) {
    const double share = total > 0.0 ? area[i] / total : 1.0 / static_cast<double>(nf);
    // share ∈ [0, 1], so the count lies in [0, wanted + 1) ⊂ [0, 2e9 + 1): the cast is defined.
    const double count = std::floor(std::min(wanted * share + uniform(options.seed, i, 0), wanted + 1.0));
    offset[i + 1] = offset[i] + static_cast<std::size_t>(std::max(count, 0.0));
  }

  std::vector<std::size_t> vertexList;
  if (options.includeVertices) {
    std::vector<char> used(nv, 0);
    for (std::size_t i = 0; i < 3 * nf; ++i) used[static_cast<std::size_t>(f[i])] = 1;
    for (std::size_t v = 0; v < nv; ++v) {
      if (used[v]) vertexList.push_back(v);
    }
  }
  MeshSamples s;
  s.vertexSamples = vertexList.size();
  s.faceSamples = offset[nf];
  s.points.resize(static_cast<Eigen::Index>(s.vertexSamples + s.faceSamples), 3);
  s.faces.assign(s.vertexSamples + s.faceSamples, -1);
  for (std::size_t k = 0; k < vertexList.size(); ++k) {
    s.points.row(static_cast<Eigen::Index>(k)) = mesh.vertices.row(static_cast<Eigen::Index>(vertexList[k]));
  }
  double* out = s.points.data() + 3 * s.vertexSamples;
  std::int64_t* outFace = s.faces.data() + s.vertexSamples;
  const auto nfl = static_cast<long long>(nf);
  const std::uint64_t seed = options.seed;
  measure_detail::ParallelErrors errors;
#pragma omp parallel for schedule(dynamic, 1024) default(none) shared(mesh, f, offset, out, outFace, nfl, seed, errors)
  for (long long ii = 0; ii < nfl; ++ii) {
    errors.run([&] {
      const auto i = static_cast<std::size_t>(ii);
      const double* a = vertexPtr(mesh, f[3 * i]);
      const double* b = vertexPtr(mesh, f[3 * i + 1]);
      const double* c = vertexPtr(mesh, f[3 * i + 2]);
      for (std::size_t j = offset[i]; j < offset[i + 1]; ++j) {
        const std::uint64_t local = j - offset[i];
        const double s1 = std::sqrt(uniform(seed, i, 2 * local + 1));
        const double r2 = uniform(seed, i, 2 * local + 2);
        const double wa = 1.0 - s1, wb = s1 * (1.0 - r2), wc = s1 * r2;
        for (std::size_t k = 0; k < 3; ++k) out[3 * j + k] = wa * a[k] + wb * b[k] + wc * c[k];
        outFace[j] = ii;
      }
    });
  }
  errors.rethrow();
  return s;
}

namespace {

/// Samples of `sampled` (position, face, distance, closest point: about 64 bytes each) and the tree of
/// `tree` (about 120 bytes a face): checked against the budget before either is built.
void checkMeasureMemory(const Mesh& sampled, const Mesh& tree, const MeasureOptions& options, const char* what) {
  const double faces = static_cast<double>(sampled.faces.rows());
  const double samples = options.samplesPerFace * faces + (options.includeVertices ? static_cast<double>(sampled.vertices.rows()) : 0.0);
  const double bytes = 64.0 * samples + 120.0 * static_cast<double>(tree.faces.rows());
  std::ostringstream s;
  s.precision(3);
  s << "about " << samples << " samples of the " << what << " (" << faces << " faces, --samples " << options.samplesPerFace
    << ")";
  requireMemory(options.limits, "measure", bytes, s.str(), "use a smaller --samples");
}

}  // namespace

DistanceReport measureDistance(const Mesh& a, const Mesh& b, const MeasureOptions& options, Interrupter* interrupter) {
  checkOptions(options);
  validateMesh(a, "first mesh");
  validateMesh(b, "second mesh");
  checkMeasureMemory(a, b, options, "first mesh");
  checkMeasureMemory(b, a, options, "second mesh");
  DistanceReport r;
  r.diagonalA = bboxDiagonal(a);
  r.diagonalB = bboxDiagonal(b);
  {
    const TriangleBvh treeB(b);
    const MeshSamples samplesA = sampleMesh(a, options);
    poll(interrupter, 0.0, "measure");
    r.forward = oneSided(samplesA, treeB, interrupter, 0.0, 50.0);
  }
  {
    const TriangleBvh treeA(a);
    MeasureOptions ob = options;
    ob.seed = options.seed + 1;
    const MeshSamples samplesB = sampleMesh(b, ob);
    r.backward = oneSided(samplesB, treeA, interrupter, 50.0, 100.0);
  }
  r.hausdorff = std::max(r.forward.max, r.backward.max);
  return r;
}

std::vector<OffsetReport::Component> offsetComponents(const Mesh& offsetMesh, const TriangleBvh& surface,
                                                      double delta, const std::vector<Index>& labels,
                                                      std::size_t count, std::size_t maxVertices) {
  if (labels.size() != static_cast<std::size_t>(offsetMesh.faces.rows())) {
    throw InvalidArgument("offset components: " + std::to_string(labels.size()) + " labels for " +
                          std::to_string(offsetMesh.faces.rows()) + " faces");
  }
  const double absDelta = std::abs(delta);
  std::vector<Index> vertexLabel(static_cast<std::size_t>(offsetMesh.vertices.rows()), -1);
  std::vector<OffsetReport::Component> components(count);
  for (Eigen::Index f = 0; f < offsetMesh.faces.rows(); ++f) {
    const Index c = labels[static_cast<std::size_t>(f)];
    if (c < 0 || static_cast<std::size_t>(c) >= count) {
      throw InvalidArgument("offset components: face " + std::to_string(f) + " has label " + std::to_string(c) +
                            " (" + std::to_string(count) + " components)");
    }
    ++components[static_cast<std::size_t>(c)].faces;
    for (int k = 0; k < 3; ++k) {
      const Index v = offsetMesh.faces(f, k);
      if (v < 0 || static_cast<std::size_t>(v) >= vertexLabel.size()) {
        throw InvalidArgument("offset components: face " + std::to_string(f) + ": vertex index " +
                              std::to_string(v) + " out of range (mesh has " + std::to_string(vertexLabel.size()) +
                              " vertices)");
      }
      vertexLabel[static_cast<std::size_t>(v)] = c;
    }
  }
  for (const Index c : vertexLabel) {
    if (c >= 0) ++components[static_cast<std::size_t>(c)].vertices;  // vertices no face uses have none
  }
  // The vertices measured: all, or every k-th of a component with more than maxVertices (k = ⌈n/max⌉).
  std::vector<std::size_t> stride(count, 1), seen(count, 0), measured(count, 0);
  if (maxVertices > 0) {
    for (std::size_t c = 0; c < count; ++c) stride[c] = (components[c].vertices + maxVertices - 1) / maxVertices;
  }
  std::vector<Eigen::Index> rows;
  rows.reserve(vertexLabel.size());
  for (std::size_t v = 0; v < vertexLabel.size(); ++v) {
    const Index c = vertexLabel[v];
    if (c < 0) continue;
    const auto cc = static_cast<std::size_t>(c);
    if (seen[cc]++ % std::max<std::size_t>(stride[cc], 1) == 0) rows.push_back(static_cast<Eigen::Index>(v));
  }
  Points queries(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    queries.row(static_cast<Eigen::Index>(i)) = offsetMesh.vertices.row(rows[i]);
  }
  const Eigen::VectorXd vd = surface.distances(queries);
  for (Eigen::Index i = 0; i < vd.size(); ++i) {
    const auto c = static_cast<std::size_t>(vertexLabel[static_cast<std::size_t>(rows[static_cast<std::size_t>(i)])]);
    OffsetReport::Component& comp = components[c];
    const double deviation = std::abs(vd[i] - absDelta);
    ++measured[c];
    comp.meanDistance += vd[i];
    comp.meanDeviation += deviation;
    comp.maxDeviation = std::max(comp.maxDeviation, deviation);
    if (vd[i] < comp.minDistance) {
      comp.minDistance = vd[i];
      comp.minAt = queries.row(i).transpose();
    }
  }
  for (std::size_t c = 0; c < count; ++c) {
    OffsetReport::Component& comp = components[c];
    if (measured[c] > 0) {
      comp.meanDistance /= static_cast<double>(measured[c]);
      comp.meanDeviation /= static_cast<double>(measured[c]);
    }
    comp.offOffset = comp.meanDeviation > 0.5 * absDelta;
  }
  return components;
}

OffsetReport measureOffset(const Mesh& offsetMesh, const Mesh& surface, double delta,
                           const MeasureOptions& options, Interrupter* interrupter) {
  checkOptions(options);
  if (!std::isfinite(delta) || delta == 0.0) {
    throw InvalidArgument("offset measurement: delta must be a non-zero number (got " + std::to_string(delta) + ")");
  }
  validateMesh(offsetMesh, "offset mesh");
  validateMesh(surface, "surface mesh");
  checkMeasureMemory(offsetMesh, surface, options, "offset mesh");
  const TriangleBvh tree(surface);
  const PseudoNormals normals(surface);
  const MeshSamples samples = sampleMesh(offsetMesh, options);
  const auto n = static_cast<long long>(samples.points.rows());
  std::vector<double> dist(static_cast<std::size_t>(n)), dev(static_cast<std::size_t>(n));
  const double absDelta = std::abs(delta);
  const bool inward = delta > 0.0;
  long long wrong = 0;
  const double* q = samples.points.data();
  poll(interrupter, 0.0, "offset measurement");
  // In chunks of samples, polling the interrupter between them (outside the parallel region).
  for (long long begin = 0; begin < n; begin += kPollChunk) {
    const long long end = std::min<long long>(n, begin + kPollChunk);
    measure_detail::ParallelErrors errors;
#pragma omp parallel reduction(+ : wrong) default(none) \
    shared(tree, normals, q, begin, end, dist, dev, absDelta, inward, errors)
    {
      std::int64_t hint = -1;  // consecutive samples are near each other (same face of O)
#pragma omp for schedule(dynamic, 256)
      for (long long i = begin; i < end; ++i) {
        errors.run([&] {
          const Eigen::Vector3d p(q[3 * i], q[3 * i + 1], q[3 * i + 2]);
          const ClosestPoint cp = tree.closest(p, hint);
          const double side = (p - cp.point).dot(normals.at(cp));
          if (inward ? side > 0.0 : side < 0.0) ++wrong;
          dist[static_cast<std::size_t>(i)] = cp.distance;
          dev[static_cast<std::size_t>(i)] = std::abs(cp.distance - absDelta);
        });
      }
    }
    errors.rethrow();
    poll(interrupter, 95.0 * static_cast<double>(end) / static_cast<double>(n), "offset measurement");
  }
  OffsetReport r;
  r.delta = delta;
  r.samples = static_cast<std::size_t>(n);
  r.wrongSide = static_cast<std::size_t>(wrong);
  r.wrongSideShare = n > 0 ? static_cast<double>(wrong) / static_cast<double>(n) : 0.0;
  std::size_t argmax = 0;
  r.distance = summarize(dist, &argmax);
  r.distance.maxAt = samples.points.row(static_cast<Eigen::Index>(argmax)).transpose();
  r.distance.maxClosest = tree.closest(r.distance.maxAt).point;
  r.deviation = summarize(dev, &argmax);
  r.deviation.maxAt = samples.points.row(static_cast<Eigen::Index>(argmax)).transpose();
  r.deviation.maxClosest = tree.closest(r.deviation.maxAt).point;
  r.relativeDistance = scaled(r.distance, 1.0 / absDelta);
  r.relativeDeviation = scaled(r.deviation, 1.0 / absDelta);

  // Components: a piece of the offset lies at distance ≈ |δ| from S; a spurious sheet does not.
  std::size_t count = 0;
  const std::vector<Index> label = faceComponents(offsetMesh, &count);
  r.components = offsetComponents(offsetMesh, tree, delta, label, count);
  for (const OffsetReport::Component& comp : r.components) r.offOffsetComponents += comp.offOffset ? 1 : 0;
  std::stable_sort(r.components.begin(), r.components.end(),
                   [](const OffsetReport::Component& a, const OffsetReport::Component& b) { return a.faces > b.faces; });
  return r;
}

}  // namespace duplexfit
