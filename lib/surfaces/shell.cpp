// The printable shell (shell.hpp): joining the zero mesh and the reversed offset mesh, the drain holes'
// distance function and the drained solid g' = min(f, δ − f, c_1, …, c_n), its polygonization, and the
// report (topology, volumes, checkMesh's intersection test on the joined mesh).
#include "duplexfit/shell.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <sstream>

#include "duplexfit/error.hpp"
#include "duplexfit/measure.hpp"
#include "duplexfit/timer.hpp"

namespace duplexfit {

namespace {

using Clock = std::chrono::steady_clock;

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

void checkOffset(double delta) {
  if (!(delta > 0.0) || !std::isfinite(delta)) {
    throw InvalidArgument("shell: the inner surface must be an inward offset, delta > 0 (got " + num(delta) +
                          "); fit with --offset D, D > 0");
  }
}

void checkHole(const DrainHole& h) {
  if (!h.point.allFinite() || !(h.radius > 0.0) || !std::isfinite(h.radius)) {
    throw InvalidArgument("--drain-hole: the point must be finite and the radius > 0 (got " + num(h.point.x()) + "," +
                          num(h.point.y()) + "," + num(h.point.z()) + "," + num(h.radius) + ")");
  }
}

/// c, ∇c and the Hessian of c at x (drainHoleDistance). a = ρ − r (radial), b = z − top (axial).
struct HoleSample {
  double value = 0.0;
  Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
  Eigen::Matrix3d hessian = Eigen::Matrix3d::Zero();
};

HoleSample holeSample(const DrainHole& h, const Eigen::Vector3d& x, bool derivatives) {
  const double dx = x.x() - h.point.x(), dy = x.y() - h.point.y();
  const double rho = std::hypot(dx, dy);
  const double a = rho - h.radius, b = x.z() - h.point.z();
  HoleSample s;
  // Outside beside the side (a > 0, b ≤ 0) or inside nearer to the side than to the top: c = a.
  const bool radial = b <= 0.0 && (a > 0.0 || a >= b);
  if (a > 0.0 && b > 0.0) {
    s.value = std::hypot(a, b);  // nearest point on the top rim
  } else {
    s.value = radial ? a : b;  // the side (outside or inside nearer to it) or the top disc
  }
  if (!derivatives) return s;
  const Eigen::Vector3d n = rho > 0.0 ? Eigen::Vector3d(dx / rho, dy / rho, 0.0) : Eigen::Vector3d::UnitX();
  Eigen::Matrix3d hRho = Eigen::Matrix3d::Zero();  // Hessian of ρ: (I − n nᵀ)/ρ in the horizontal plane
  if (rho > 0.0) {
    hRho.topLeftCorner<2, 2>() = (Eigen::Matrix2d::Identity() - n.head<2>() * n.head<2>().transpose()) / rho;
  }
  const Eigen::Vector3d ez = Eigen::Vector3d::UnitZ();
  if (a > 0.0 && b > 0.0) {
    s.gradient = (a * n + b * ez) / s.value;
    s.hessian = (n * n.transpose() + a * hRho + ez * ez.transpose() - s.gradient * s.gradient.transpose()) / s.value;
  } else if (radial) {
    s.gradient = n;
    s.hessian = hRho;
  } else {
    s.gradient = ez;
  }
  return s;
}

double faceVolume(const Mesh& m, Eigen::Index f) {
  const Eigen::Vector3d a = m.vertices.row(m.faces(f, 0)).transpose();
  const Eigen::Vector3d b = m.vertices.row(m.faces(f, 1)).transpose();
  const Eigen::Vector3d c = m.vertices.row(m.faces(f, 2)).transpose();
  return a.dot(b.cross(c)) / 6.0;
}

double faceArea(const Mesh& m, Eigen::Index f) {
  const Eigen::Vector3d a = m.vertices.row(m.faces(f, 0)).transpose();
  const Eigen::Vector3d b = m.vertices.row(m.faces(f, 1)).transpose();
  const Eigen::Vector3d c = m.vertices.row(m.faces(f, 2)).transpose();
  return 0.5 * (b - a).cross(c - a).norm();
}

/// Drops the cavity components (negative enclosed volume) below `fraction` of the mesh's area.
Mesh dropSmallCavities(Mesh mesh, double fraction, std::size_t& dropped) {
  dropped = 0;
  if (fraction <= 0.0 || mesh.faces.rows() == 0) return mesh;
  std::size_t count = 0;
  const std::vector<Index> label = faceComponents(mesh, &count);
  std::vector<double> area(count, 0.0), volume(count, 0.0);
  double total = 0.0;
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    const auto l = static_cast<std::size_t>(label[static_cast<std::size_t>(f)]);
    const double a = faceArea(mesh, f);
    area[l] += a;
    total += a;
    volume[l] += faceVolume(mesh, f);
  }
  std::vector<char> drop(count, 0);
  for (std::size_t l = 0; l < count; ++l) {
    drop[l] = volume[l] < 0.0 && area[l] < fraction * total ? 1 : 0;
    dropped += static_cast<std::size_t>(drop[l]);
  }
  if (dropped == 0) return mesh;
  std::vector<char> keep(static_cast<std::size_t>(mesh.faces.rows()));
  for (std::size_t f = 0; f < keep.size(); ++f) keep[f] = drop[static_cast<std::size_t>(label[f])] ? 0 : 1;
  return keepFaces(mesh, keep);
}

/// Topology, volume and the intersection test of the finished shell mesh.
void finishReport(const Mesh& mesh, const ShellOptions& options, ShellReport& r) {
  r.topology = analyzeTopology(mesh);
  r.volume = signedVolume(mesh);
  if (options.checkIntersections && r.topology.faces > r.topology.degenerateFaces) {
    CheckOptions check;
    check.listedPairs = 0;
    check.candidatePairBudget = options.candidatePairBudget;
    const MeshCheck c = checkMesh(mesh, check);
    r.intersectionsChecked = c.selfIntersectionsChecked;
    r.intersections = c.selfIntersections;
    r.intersectionsComplete = c.selfIntersectionsComplete;
  }
}

}  // namespace

double drainHoleDistance(const DrainHole& hole, const Eigen::Vector3d& x) { return holeSample(hole, x, false).value; }

FieldSamples drainedShellSamples(const Points& queries, const FieldSamples& f, double offset,
                                 const std::vector<DrainHole>& holes) {
  const Eigen::Index n = queries.rows();
  if (f.values.size() != n) {
    throw InvalidArgument("drained shell: " + std::to_string(f.values.size()) + " field values for " +
                          std::to_string(n) + " points");
  }
  const bool gradients = f.gradients.rows() == n && n > 0;
  const bool hessians = gradients && f.hessians.rows() == n;
  FieldSamples out;
  out.values.resize(n);
  if (gradients) out.gradients.resize(n, 3);
  if (hessians) out.hessians.resize(n, 6);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double fi = f.values[i];
    // The piece that attains the minimum: 0 (f), 1 (δ − f), 2 + j (hole j).
    double g = fi;
    std::size_t piece = 0;
    if (offset - fi < g) {
      g = offset - fi;
      piece = 1;
    }
    const Eigen::Vector3d x = queries.row(i).transpose();
    HoleSample best;
    for (std::size_t j = 0; j < holes.size(); ++j) {
      const HoleSample s = holeSample(holes[j], x, gradients);
      if (s.value < g) {
        g = s.value;
        piece = 2 + j;
        best = s;
      }
    }
    out.values[i] = g;
    if (!gradients) continue;
    const double sign = piece == 1 ? -1.0 : 1.0;
    if (piece < 2) {
      out.gradients.row(i) = sign * f.gradients.row(i);
      if (hessians) out.hessians.row(i) = sign * f.hessians.row(i);
    } else {
      out.gradients.row(i) = best.gradient.transpose();
      if (hessians) {
        const Eigen::Matrix3d& h = best.hessian;
        out.hessians.row(i) << h(0, 0), h(0, 1), h(0, 2), h(1, 1), h(1, 2), h(2, 2);
      }
    }
  }
  return out;
}

std::vector<DrainHole> autoDrainHoles(const Mesh& offsetMesh, double radius) {
  if (!(radius > 0.0) || !std::isfinite(radius)) {
    throw InvalidArgument("--drain-hole auto: the radius must be > 0 (got " + num(radius) + ")");
  }
  std::size_t count = 0;
  const std::vector<Index> label = faceComponents(offsetMesh, &count);
  std::vector<double> volume(count, 0.0), top(count, -std::numeric_limits<double>::infinity());
  std::vector<Index> lowest(count, -1);
  for (Eigen::Index f = 0; f < offsetMesh.faces.rows(); ++f) {
    const auto l = static_cast<std::size_t>(label[static_cast<std::size_t>(f)]);
    volume[l] += faceVolume(offsetMesh, f);
    for (int k = 0; k < 3; ++k) {
      const Index v = offsetMesh.faces(f, k);
      const double z = offsetMesh.vertices(v, 2);
      top[l] = std::max(top[l], z);
      if (lowest[l] < 0 || z < offsetMesh.vertices(lowest[l], 2)) lowest[l] = v;
    }
  }
  std::vector<DrainHole> holes;
  for (std::size_t l = 0; l < count; ++l) {
    if (!(volume[l] > 0.0)) continue;  // the inner boundary of a region {f > δ}, not a cavity
    DrainHole h;
    h.point = offsetMesh.vertices.row(lowest[l]).transpose();
    h.point.z() += std::min(radius, 0.5 * (top[l] - h.point.z()));
    h.radius = radius;
    holes.push_back(h);
  }
  return holes;
}

void parseDrainHoleSpec(const std::string& text, ShellOptions& options) {
  std::vector<std::string> items;
  std::size_t begin = 0;
  while (begin <= text.size()) {
    const std::size_t end = std::min(text.find(',', begin), text.size());
    items.push_back(text.substr(begin, end - begin));
    begin = end + 1;
  }
  const bool automatic = !items.empty() && items[0] == "auto";
  const std::string usage = "--drain-hole '" + text + "': expected x,y,z,r (four numbers, r > 0), auto or auto,r";
  if (automatic ? items.size() > 2 : items.size() != 4) throw InvalidArgument(usage);
  std::vector<double> v;
  for (std::size_t i = automatic ? 1 : 0; i < items.size(); ++i) {
    char* stop = nullptr;
    const double d = std::strtod(items[i].c_str(), &stop);
    if (items[i].empty() || *stop != '\0' || !std::isfinite(d)) throw InvalidArgument(usage);
    v.push_back(d);
  }
  if (automatic) {
    if (!v.empty() && !(v[0] > 0.0)) throw InvalidArgument(usage);
    options.autoDrainHoles = true;
    options.autoDrainRadius = v.empty() ? 0.0 : v[0];
    return;
  }
  if (!(v[3] > 0.0)) throw InvalidArgument(usage);
  options.drainHoles.push_back({Eigen::Vector3d(v[0], v[1], v[2]), v[3]});
}

std::vector<DrainHole> parseDrainHoles(const std::vector<std::string>& texts) {
  ShellOptions o;
  for (const std::string& t : texts) {
    parseDrainHoleSpec(t, o);
    if (o.autoDrainHoles) {
      throw InvalidArgument("--drain-hole " + t + ": automatic holes need the offset mesh (fit --shell or mesh --shell; "
                            "their report lists the holes placed): give x,y,z,r here");
    }
  }
  return o.drainHoles;
}

double ShellReport::relativeDifference() const noexcept {
  const double reference = zeroMinusOffsetVolume();
  return reference != 0.0 ? (volume - reference) / reference : std::numeric_limits<double>::quiet_NaN();
}

bool ShellReport::valid() const noexcept {
  return topology.watertight() && topology.manifold() && topology.oriented() && volume > 0.0 && !intersects() &&
         (!intersectionsChecked || intersectionsComplete);
}

ShellResult buildShell(const Mesh& zero, const Mesh& offset, const ShellOptions& options) {
  const auto start = Clock::now();
  checkOffset(options.offset);
  if (options.drained()) {
    throw InvalidArgument("shell: drain holes are cut in the field (drainShell), not in the meshes");
  }
  ShellResult result;
  ShellReport& r = result.report;
  r.offset = options.offset;
  r.zeroVolume = signedVolume(zero);
  r.offsetVolume = signedVolume(offset);
  Mesh& m = result.mesh;
  const Eigen::Index nz = zero.vertices.rows();
  m.vertices.resize(nz + offset.vertices.rows(), 3);
  m.vertices << zero.vertices, offset.vertices;
  m.faces.resize(zero.faces.rows() + offset.faces.rows(), 3);
  m.faces.topRows(zero.faces.rows()) = zero.faces;
  // Reversed: (a, b, c) → (a, c, b), so the inner surface's normals point into the cavity.
  for (Eigen::Index f = 0; f < offset.faces.rows(); ++f) {
    const Eigen::Index row = zero.faces.rows() + f;
    m.faces(row, 0) = offset.faces(f, 0) + static_cast<std::int32_t>(nz);
    m.faces(row, 1) = offset.faces(f, 2) + static_cast<std::int32_t>(nz);
    m.faces(row, 2) = offset.faces(f, 1) + static_cast<std::int32_t>(nz);
  }
  finishReport(m, options, r);
  r.seconds = secondsSince(start);
  return result;
}

ShellResult drainShell(const FieldSampler& field, const GridSpec& grid, const Mesh& zero, const Mesh& offset,
                       const ShellOptions& options, const PolygonizeOptions& polygonizeOptions,
                       Interrupter* interrupter) {
  const auto start = Clock::now();
  checkOffset(options.offset);
  if (!(options.minCavityFraction >= 0.0 && options.minCavityFraction < 1.0)) {
    throw InvalidArgument("shell: minCavityFraction must be in [0, 1) (got " + num(options.minCavityFraction) + ")");
  }
  if (!field) throw InvalidArgument("shell: no field to sample");
  ShellResult result;
  ShellReport& r = result.report;
  const double delta = options.offset;
  r.offset = delta;
  r.zeroVolume = signedVolume(zero);
  r.offsetVolume = signedVolume(offset);
  r.drainHoles = options.drainHoles;
  if (options.autoDrainHoles) {
    const std::vector<DrainHole> placed =
        autoDrainHoles(offset, options.autoDrainRadius > 0.0 ? options.autoDrainRadius : delta);
    r.drainHoles.insert(r.drainHoles.end(), placed.begin(), placed.end());
  }
  for (const DrainHole& h : r.drainHoles) checkHole(h);
  const std::vector<DrainHole>& holes = r.drainHoles;
  const FieldSampler drained = [&](const Points& q, Eigen::VectorXd& values) {
    field(q, values);
    if (values.size() != q.rows()) return;  // polygonize reports the wrong count
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
      double g = std::min(values[i], delta - values[i]);
      const Eigen::Vector3d x = q.row(i).transpose();
      for (const DrainHole& h : holes) g = std::min(g, drainHoleDistance(h, x));
      values[i] = g;
    }
  };
  // No local refinement here: the shell's wall is |δ| thick, often a node or two, so nearly every cell of
  // it would count as thin (the zero and offset meshes are refined on their own).
  PolygonizeOptions plain = polygonizeOptions;
  plain.refineLevels = 0;
  PolygonizeResult p = polygonize(drained, grid, {0.0}, plain, interrupter);
  result.mesh = dropSmallCavities(std::move(p.meshes[0]), options.minCavityFraction, r.droppedCavities);
  finishReport(result.mesh, options, r);
  r.seconds = secondsSince(start);
  return result;
}

}  // namespace duplexfit
