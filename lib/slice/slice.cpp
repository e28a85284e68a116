// Slicing (docs/method.md §10): plane sampling in bands of rows (FieldEvaluator batches), marching squares
// with oriented segments and asymptotic-decider saddles, vertices refined along their cell edge on the
// true f, loops joined by edge identity, nested into a containment tree, and the adaptive thickness from
// the cusp height and the vertical normal curvature.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iomanip>
#include <sstream>
#include <unordered_map>
#include <utility>

#include <Eigen/Eigenvalues>

#include "duplexfit/error.hpp"
#include "duplexfit/timer.hpp"
#include "duplexfit/slice.hpp"

namespace duplexfit {

namespace {

using Clock = std::chrono::steady_clock;

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// The iso-values contoured and on which side of each the region lies.
struct Level {
  double value = 0.0;
  bool regionAbove = true;  // region on the f > value side (else on the f ≤ value side)
};

// A contour vertex: the crossing on one cell edge a → b, refined by a bracketed root search in the edge
// parameter s ∈ [0, 1]; g = f − level.
struct Vertex {
  int level = 0;
  Eigen::Vector2d a, b;
  double sLo = 0.0, gLo = 0.0, sHi = 1.0, gHi = 0.0;  // g(sLo) ≤ 0 < g(sHi)
  double s = 0.0;
  double bestS = 0.0, bestAbsG = std::numeric_limits<double>::infinity();
  int lastSide = 0;  // Illinois: +1 when sHi was replaced last, −1 for sLo
  Eigen::Vector2d at() const { return a + s * (b - a); }
};

// The contouring of one plane, before refinement.
struct PlaneContours {
  std::vector<Vertex> vertices;
  std::vector<int> next;  // next[v]: the vertex the region-on-the-left segment from v goes to, −1 none
  bool broken = false;    // a vertex without exactly one successor (should not happen)
  std::size_t samples = 0;
};

class BorderHit : public std::exception {};

double signedArea(const Points2& p) {
  double a = 0.0;
  const Eigen::Index n = p.rows();
  for (Eigen::Index i = 0, j = n - 1; i < n; j = i++) a += p(j, 0) * p(i, 1) - p(i, 0) * p(j, 1);
  return 0.5 * a;
}

bool pointInPolygon(const Points2& p, double x, double y) {
  bool inside = false;
  const Eigen::Index n = p.rows();
  for (Eigen::Index i = 0, j = n - 1; i < n; j = i++) {
    const double yi = p(i, 1), yj = p(j, 1);
    if ((yi > y) != (yj > y)) {
      const double xc = p(j, 0) + (y - yj) * (p(i, 0) - p(j, 0)) / (yi - yj);
      if (x < xc) inside = !inside;
    }
  }
  return inside;
}

}  // namespace

// ---- small public helpers ------------------------------------------------------------------------

SliceMode parseSliceMode(const std::string& text) {
  if (text == "zero") return SliceMode::Zero;
  if (text == "shell") return SliceMode::Shell;
  throw InvalidArgument("slice mode '" + text + "' is not 'zero' or 'shell'");
}

const char* cuspRuleName(CuspRule rule) noexcept { return rule == CuspRule::Paper ? "paper" : "geometric"; }

CuspRule parseCuspRule(const std::string& text) {
  if (text == "geometric") return CuspRule::Geometric;
  if (text == "paper") return CuspRule::Paper;
  throw InvalidArgument("cusp rule '" + text + "' is not 'geometric' or 'paper'");
}

int parseAxis(const std::string& text) {
  if (text == "x" || text == "X" || text == "0") return 0;
  if (text == "y" || text == "Y" || text == "1") return 1;
  if (text == "z" || text == "Z" || text == "2") return 2;
  throw InvalidArgument("axis '" + text + "' is not x, y or z");
}

Eigen::Vector2d planeCoordinates(const Eigen::Vector3d& x, int axis) {
  return {x[(axis + 1) % 3], x[(axis + 2) % 3]};
}

Eigen::Vector3d worldPoint(const Eigen::Vector2d& uv, double height, int axis) {
  Eigen::Vector3d x;
  x[axis] = height;
  x[(axis + 1) % 3] = uv.x();
  x[(axis + 2) % 3] = uv.y();
  return x;
}

std::size_t SliceLayer::vertexCount() const noexcept {
  std::size_t n = 0;
  for (const SliceLoop& l : loops) n += static_cast<std::size_t>(l.points.rows());
  return n;
}

double cuspThickness(double kappaV, double c, double tau, double tMax, CuspRule rule) {
  bool convex = kappaV < 0.0;
  if (rule == CuspRule::Geometric) {
    convex = c >= 0.0;
  }
  c = std::min(1.0, std::abs(c));
  const double rho = kappaV != 0.0 ? 1.0 / std::abs(kappaV) : std::numeric_limits<double>::infinity();
  if (!(rho <= 1e6 * tau)) return c > 0.0 ? std::min(tau / c, tMax) : tMax;  // flat (also ρ = ∞, NaN)
  const double rc = rho * c;
  if (convex) {
    // −ρc + √(ρ²c² + 2ρτ + τ²), written without cancellation.
    const double q = 2.0 * rho * tau + tau * tau;
    return q / (rc + std::sqrt(rc * rc + q));
  }
  const double rad = rc * rc - 2.0 * rho * tau + tau * tau;
  if (rad < 0.0) return tMax;  // the concave cusp never reaches τ
  // ρc − √rad = (2ρτ − τ²)/(ρc + √rad)
  return (2.0 * rho * tau - tau * tau) / (rc + std::sqrt(rad));
}

double vertexThickness(const Eigen::Vector3d& gradient, const Eigen::Matrix<double, 1, 6>& h6, int axis, double tau,
                       double tMax, CuspRule rule) {
  const double gn = gradient.norm();
  if (!(gn > 1e-12)) return std::numeric_limits<double>::infinity();  // critical point: no normal
  const Eigen::Vector3d n = gradient / gn;
  Eigen::Matrix3d h;
  h << h6[0], h6[1], h6[2], h6[1], h6[3], h6[4], h6[2], h6[4], h6[5];
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  a[axis] = 1.0;
  const double na = n[axis];
  Eigen::Vector3d tv = a - na * n;
  const double tvn = tv.norm();
  auto thickness = [&](double kappa) {
    const double c = rule == CuspRule::Geometric ? (kappa >= 0.0 ? 1.0 : -1.0) * na : std::abs(na);
    return cuspThickness(kappa, c, tau, tMax, rule);
  };
  if (tvn < 1e-9) {
    // Horizontal tangent plane: both principal directions, keep the thinner layer (§10.3 choice).
    Eigen::Vector3d e1 = n.unitOrthogonal();
    Eigen::Vector3d e2 = n.cross(e1);
    Eigen::Matrix2d s;
    s << e1.dot(h * e1), e1.dot(h * e2), e2.dot(h * e1), e2.dot(h * e2);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(s / gn);
    return std::min(thickness(es.eigenvalues()[0]), thickness(es.eigenvalues()[1]));
  }
  tv /= tvn;
  return thickness(tv.dot(h * tv) / gn);
}

// ---- the slicer ----------------------------------------------------------------------------------

struct Slicer::Impl {
  std::unique_ptr<FieldEvaluator> evaluator;
  FieldFunction function;
  Eigen::AlignedBox3d bounds;  // sliced box (grown by |δ| for an outward shell)
  SliceOptions options;
  std::vector<Level> levels;
  std::vector<double> levelValues;
  int u = 0, v = 1;

  FieldSamples eval(const Points& q, FieldDerivatives d) const {
    return evaluator ? evaluator->evaluate(q, d) : function(q, d);
  }

  void setup(const Eigen::AlignedBox3d& box, const std::vector<double>& offsets, SliceOptions o);
  PlaneContours contour(double height, double pad, bool clampBorder) const;
  void refine(PlaneContours& pc, double height, std::size_t& evaluations) const;
  SliceLayer layerAt(double height, std::size_t* samples, std::size_t* refineEvals) const;
};

void Slicer::Impl::setup(const Eigen::AlignedBox3d& box, const std::vector<double>& offsets, SliceOptions o) {
  if (o.axis < 0 || o.axis > 2) throw InvalidArgument("slice: axis " + std::to_string(o.axis) + " is not 0 (x), 1 (y) or 2 (z)");
  if (box.isEmpty() || !box.min().allFinite() || !box.max().allFinite()) {
    throw InvalidArgument("slice: the field has an empty or invalid bounding box");
  }
  const bool uniform = o.layer != 0.0;
  if (uniform && !(o.layer > 0.0 && std::isfinite(o.layer))) {
    throw InvalidArgument("slice: the uniform layer thickness (layer) must be positive, got " + num(o.layer));
  }
  if (!uniform && !(o.cusp > 0.0 && std::isfinite(o.cusp))) {
    throw InvalidArgument("slice: the cusp height τ (cusp) must be positive, got " + num(o.cusp));
  }
  if (o.cusp < 0.0 || !std::isfinite(o.cusp)) throw InvalidArgument("slice: the cusp height τ (cusp) must be positive, got " + num(o.cusp));
  if (!(o.minLayer >= 0.0) || !std::isfinite(o.minLayer)) throw InvalidArgument("slice: the minimum layer thickness (minLayer) must be positive, got " + num(o.minLayer));
  if (!(o.maxLayer >= 0.0) || !std::isfinite(o.maxLayer)) throw InvalidArgument("slice: the maximum layer thickness (maxLayer) must be positive, got " + num(o.maxLayer));
  if (!(o.grid >= 0.0) || !std::isfinite(o.grid)) throw InvalidArgument("slice: the grid step (grid) must be positive, got " + num(o.grid));
  if (o.refineSteps < 0 || o.refineSteps > 64) throw InvalidArgument("slice: refineSteps must be in 0..64, got " + std::to_string(o.refineSteps));
  if (o.batchPoints < 16) throw InvalidArgument("slice: batchPoints must be at least 16");
  if (!uniform) {
    if (o.minLayer == 0.0) o.minLayer = o.cusp / 4.0;
    if (o.maxLayer == 0.0) o.maxLayer = 5.0 * o.cusp;
    if (o.minLayer > o.maxLayer) {
      throw InvalidArgument("slice: the minimum layer thickness " + num(o.minLayer) + " exceeds the maximum " + num(o.maxLayer));
    }
  }
  double delta = 0.0;
  levels.clear();
  if (o.mode == SliceMode::Shell) {
    if (offsets.empty()) throw InvalidArgument("slice: shell mode needs a field fitted with an offset (the field has none)");
    if (o.offsetIndex < 0 || o.offsetIndex >= static_cast<int>(offsets.size())) {
      throw InvalidArgument("slice: offsetIndex " + std::to_string(o.offsetIndex) + " is out of range (the field has " +
                            std::to_string(offsets.size()) + " offsets)");
    }
    delta = offsets[static_cast<std::size_t>(o.offsetIndex)];
    if (!(delta != 0.0) || !std::isfinite(delta)) throw InvalidArgument("slice: the field's offset is zero or invalid");
    // δ > 0: {0 ≤ f ≤ δ}; δ < 0: {δ ≤ f ≤ 0}.
    levels.push_back({0.0, delta > 0.0});
    levels.push_back({delta, delta < 0.0});
  } else {
    levels.push_back({0.0, true});
  }
  levelValues.clear();
  for (const Level& l : levels) levelValues.push_back(l.value);
  bounds = box;
  if (delta < 0.0) {
    bounds.min().array() += delta;
    bounds.max().array() -= delta;
  }
  const double diag = box.diagonal().norm();
  if (o.grid == 0.0) o.grid = bounds.sizes().maxCoeff() / 200.0;
  if (!(o.grid > 0.0)) throw InvalidArgument("slice: the bounding box is degenerate (no grid step)");
  if (std::isnan(o.start)) o.start = bounds.min()[o.axis] + 1e-6 * diag;
  if (std::isnan(o.end)) o.end = bounds.max()[o.axis];
  if (!std::isfinite(o.start) || !std::isfinite(o.end) || o.end < o.start) {
    throw InvalidArgument("slice: the height range [" + num(o.start) + ", " + num(o.end) + "] is empty or invalid");
  }
  u = (o.axis + 1) % 3;
  v = (o.axis + 2) % 3;
  // Bounded work, checked before any sampling: the layer count, the plane samples of one layer, and a
  // grid that can still see the part.
  const double span = o.end - o.start;
  const double step = uniform ? o.layer : o.minLayer;
  const double layers = span / step;
  if (layers > static_cast<double>(o.maxLayers)) {
    throw InvalidArgument("slice: the plan has up to " + num(std::ceil(layers)) + " layers (height range " + num(span) +
                          " / " + (uniform ? "layer " : "minimum layer ") + num(step) + "), more than maxLayers = " +
                          std::to_string(o.maxLayers) + "; use a thicker " + (uniform ? "--layer" : "--min-layer or --cusp"));
  }
  const double extentU = bounds.sizes()[u], extentV = bounds.sizes()[v];
  const double samples = (std::floor(extentU / o.grid) + 3.0) * (std::floor(extentV / o.grid) + 3.0);
  if (samples > static_cast<double>(o.maxPlaneSamples)) {
    throw InvalidArgument("slice: the grid step " + num(o.grid) + " gives " + num(samples) +
                          " samples a layer, more than maxPlaneSamples = " + std::to_string(o.maxPlaneSamples) +
                          "; use a coarser --grid");
  }
  if (o.grid > 0.25 * std::max(extentU, extentV)) {
    throw InvalidArgument("slice: the grid step " + num(o.grid) + " is more than a quarter of the part's extent " +
                          num(std::max(extentU, extentV)) + ": the contours would miss the part; use a finer --grid");
  }
  {
    // Every layer's loops are kept (and copied once, placed on the plate): per level set, a contour about as
    // long as the box's perimeter in grid steps, 48 bytes a vertex in all; plus one band of plane samples
    // (query point, value, previous row) and its vertex table.
    const double perimeter = 2.0 * (std::floor(extentU / o.grid) + std::floor(extentV / o.grid) + 6.0);
    const double contours = std::ceil(layers) * static_cast<double>(levels.size()) * perimeter * 48.0;
    const double band = static_cast<double>(std::min<double>(samples, static_cast<double>(o.batchPoints))) * 64.0;
    requireMemory(o.limits, "slice", contours + band,
                  std::string(uniform ? "" : "up to ") + num(std::ceil(layers)) + " layers of " + num(samples) +
                      " plane samples (grid " + num(o.grid) + ")",
                  std::string("use a thicker ") + (uniform ? "--layer" : "--min-layer or --cusp") + " or a coarser --grid");
  }
  options = o;
}

PlaneContours Slicer::Impl::contour(double height, double pad, bool clampBorder) const {
  const double g = options.grid;
  const double u0 = bounds.min()[u] - pad, v0 = bounds.min()[v] - pad;
  const auto nx = static_cast<std::int64_t>(std::ceil((bounds.max()[u] + pad - u0) / g)) + 1;
  const auto ny = static_cast<std::int64_t>(std::ceil((bounds.max()[v] + pad - v0) / g)) + 1;
  const int nl = static_cast<int>(levels.size());
  const double lowest = *std::min_element(levelValues.begin(), levelValues.end());
  const std::int64_t rowsPerBand =
      std::max<std::int64_t>(1, static_cast<std::int64_t>(options.batchPoints) / std::max<std::int64_t>(nx, 1));

  PlaneContours pc;
  std::unordered_map<std::uint64_t, int> vertexOf;
  std::vector<std::pair<int, int>> segments;
  std::vector<double> prev;  // values of the last row of the previous band
  std::vector<double> vals;
  Points q;

  auto node = [&](std::int64_t i, std::int64_t j) {
    return Eigen::Vector2d(u0 + static_cast<double>(i) * g, v0 + static_cast<double>(j) * g);
  };
  // The vertex on edge `id` (2·node + 0 horizontal, + 1 vertical) for level l, from node p (value fp) to q.
  auto vertex = [&](std::uint64_t id, int l, const Eigen::Vector2d& pa, double ga, const Eigen::Vector2d& pb,
                    double gb) {
    const std::uint64_t key = id * static_cast<std::uint64_t>(nl) + static_cast<std::uint64_t>(l);
    const auto it = vertexOf.find(key);
    if (it != vertexOf.end()) return it->second;
    Vertex x;
    x.level = l;
    x.a = pa;
    x.b = pb;
    if (ga > 0.0) {  // a inside: bracket [s=1 (outside), s=0 (inside)]
      x.sLo = 1.0;
      x.gLo = gb;
      x.sHi = 0.0;
      x.gHi = ga;
    } else {
      x.sLo = 0.0;
      x.gLo = ga;
      x.sHi = 1.0;
      x.gHi = gb;
    }
    x.s = x.sLo - x.gLo * (x.sHi - x.sLo) / (x.gHi - x.gLo);
    x.bestS = x.s;
    const int index = static_cast<int>(pc.vertices.size());
    pc.vertices.push_back(x);
    vertexOf.emplace(key, index);
    return index;
  };

  for (std::int64_t r0 = 0; r0 < ny; r0 += rowsPerBand) {
    const std::int64_t r1 = std::min(ny, r0 + rowsPerBand);
    const std::int64_t rows = r1 - r0;
    q.resize(rows * nx, 3);
    for (std::int64_t j = 0; j < rows; ++j) {
      for (std::int64_t i = 0; i < nx; ++i) {
        const Eigen::Vector2d p = node(i, r0 + j);
        Eigen::Index row = j * nx + i;
        q(row, options.axis) = height;
        q(row, u) = p.x();
        q(row, v) = p.y();
      }
    }
    const Eigen::VectorXd f = eval(q, FieldDerivatives::None).values;
    pc.samples += static_cast<std::size_t>(q.rows());
    // Rows in the buffer: the previous band's last row (if any), then this band's rows.
    const std::int64_t base = r0 > 0 ? r0 - 1 : r0;
    vals.assign(prev.begin(), prev.end());
    vals.insert(vals.end(), f.data(), f.data() + f.size());
    const std::int64_t bufferRows = static_cast<std::int64_t>(vals.size()) / nx;
    // The padded border must be outside every level, or loops would be cut open.
    for (std::int64_t j = base; j < base + bufferRows; ++j) {
      const bool borderRow = j == 0 || j == ny - 1;
      for (std::int64_t i = 0; i < nx; ++i) {
        if (!borderRow && i != 0 && i != nx - 1) continue;
        double& x = vals[static_cast<std::size_t>((j - base) * nx + i)];
        if (!(x <= lowest)) {
          if (!clampBorder) throw BorderHit();
          x = lowest - std::abs(lowest) * 1e-9 - 1e-300;
        }
      }
    }
    for (std::int64_t j = base; j + 1 < base + bufferRows; ++j) {
      const double* r = &vals[static_cast<std::size_t>((j - base) * nx)];
      const double* s = r + nx;
      for (std::int64_t i = 0; i + 1 < nx; ++i) {
        const double c[4] = {r[i], r[i + 1], s[i + 1], s[i]};  // corners counter-clockwise from (i, j)
        for (int l = 0; l < nl; ++l) {
          const double lv = levels[static_cast<std::size_t>(l)].value;
          double gk[4];
          bool in[4];
          int count = 0;
          for (int k = 0; k < 4; ++k) {
            gk[k] = std::isnan(c[k]) ? -1.0 : c[k] - lv;
            in[k] = gk[k] > 0.0;
            count += in[k] ? 1 : 0;
          }
          if (count == 0 || count == 4) continue;
          const std::uint64_t nodeId = static_cast<std::uint64_t>(j * nx + i);
          const std::uint64_t nodeUp = static_cast<std::uint64_t>((j + 1) * nx + i);
          const Eigen::Vector2d p0 = node(i, j), p1 = node(i + 1, j), p2 = node(i + 1, j + 1), p3 = node(i, j + 1);
          // Edge k runs from corner k to corner k + 1; its vertex uses the edge's canonical direction.
          auto edgeVertex = [&](int k) {
            switch (k) {
              case 0: return vertex(2 * nodeId, l, p0, gk[0], p1, gk[1]);
              case 1: return vertex(2 * (nodeId + 1) + 1, l, p1, gk[1], p2, gk[2]);
              case 2: return vertex(2 * nodeUp, l, p3, gk[3], p2, gk[2]);
              default: return vertex(2 * nodeId + 1, l, p0, gk[0], p3, gk[3]);
            }
          };
          int exits[2], entries[2], ne = 0, nn = 0;
          for (int k = 0; k < 4; ++k) {
            const bool a = in[k], b = in[(k + 1) % 4];
            if (a && !b) exits[ne++] = k;
            if (!a && b) entries[nn++] = k;
          }
          auto add = [&](int from, int to) {
            int x = edgeVertex(from), y = edgeVertex(to);
            if (!levels[static_cast<std::size_t>(l)].regionAbove) std::swap(x, y);
            segments.emplace_back(x, y);
          };
          if (ne == 1) {
            add(exits[0], entries[0]);
          } else {
            // Saddle: the asymptotic decider (value of the bilinear interpolant at its saddle point).
            const double den = gk[0] + gk[2] - gk[1] - gk[3];
            const double centre = den != 0.0 ? (gk[0] * gk[2] - gk[1] * gk[3]) / den : 0.25 * (gk[0] + gk[1] + gk[2] + gk[3]);
            const bool centreIn = centre > 0.0;
            for (int e = 0; e < 2; ++e) add(exits[e], centreIn ? (exits[e] + 1) % 4 : (exits[e] + 3) % 4);
          }
        }
      }
    }
    prev.assign(vals.end() - nx, vals.end());
  }
  pc.next.assign(pc.vertices.size(), -1);
  std::vector<int> incoming(pc.vertices.size(), 0);
  for (const auto& [from, to] : segments) {
    if (pc.next[static_cast<std::size_t>(from)] != -1) pc.broken = true;
    pc.next[static_cast<std::size_t>(from)] = to;
    ++incoming[static_cast<std::size_t>(to)];
  }
  for (std::size_t i = 0; i < pc.vertices.size(); ++i) {
    if (pc.next[i] == -1 || incoming[i] != 1) pc.broken = true;
  }
  return pc;
}

void Slicer::Impl::refine(PlaneContours& pc, double height, std::size_t& evaluations) const {
  const auto n = static_cast<Eigen::Index>(pc.vertices.size());
  if (n == 0) return;
  const auto batch = static_cast<Eigen::Index>(options.batchPoints);
  Points q;
  for (int step = 0; step < options.refineSteps; ++step) {
    for (Eigen::Index b0 = 0; b0 < n; b0 += batch) {
      const Eigen::Index m = std::min(batch, n - b0);
      q.resize(m, 3);
      for (Eigen::Index i = 0; i < m; ++i) {
        const Eigen::Vector2d p = pc.vertices[static_cast<std::size_t>(b0 + i)].at();
        q(i, options.axis) = height;
        q(i, u) = p.x();
        q(i, v) = p.y();
      }
      const Eigen::VectorXd f = eval(q, FieldDerivatives::None).values;
      evaluations += static_cast<std::size_t>(m);
      for (Eigen::Index i = 0; i < m; ++i) {
        Vertex& x = pc.vertices[static_cast<std::size_t>(b0 + i)];
        const double gs = f[i] - levels[static_cast<std::size_t>(x.level)].value;
        if (!std::isfinite(gs)) continue;
        if (std::abs(gs) < x.bestAbsG) {
          x.bestAbsG = std::abs(gs);
          x.bestS = x.s;
        }
        if (gs == 0.0) continue;
        // Illinois regula falsi: keep the bracket, halve the stale end's value when one end repeats.
        if (gs > 0.0) {
          x.sHi = x.s;
          x.gHi = gs;
          if (x.lastSide == 1) x.gLo *= 0.5;
          x.lastSide = 1;
        } else {
          x.sLo = x.s;
          x.gLo = gs;
          if (x.lastSide == -1) x.gHi *= 0.5;
          x.lastSide = -1;
        }
        const double den = x.gHi - x.gLo;
        double s = den > 0.0 ? x.sLo - x.gLo * (x.sHi - x.sLo) / den : 0.5 * (x.sLo + x.sHi);
        const double lo = std::min(x.sLo, x.sHi), hi = std::max(x.sLo, x.sHi);
        if (!(s > lo && s < hi)) s = 0.5 * (x.sLo + x.sHi);
        x.s = s;
      }
    }
  }
  for (Vertex& x : pc.vertices) {
    if (options.refineSteps > 0) x.s = x.bestS;
  }
}

SliceLayer Slicer::Impl::layerAt(double height, std::size_t* samples, std::size_t* refineEvals) const {
  SliceLayer layer;
  layer.height = height;
  const double g = options.grid;
  PlaneContours pc;
  // Pad the box by 2g; when a level set still reaches the border, pad more (8g, 32g), and at last clamp
  // the border samples outside (the loops then close along the border: touchesBoundary).
  double pad = 2.0 * g;
  for (int attempt = 0;; ++attempt) {
    try {
      pc = contour(height, pad, attempt == 3);
      layer.touchesBoundary = attempt == 3;
      break;
    } catch (const BorderHit&) {
      if (attempt < 2) pad = 4.0 * pad;
    }
  }
  if (samples) *samples += pc.samples;
  std::size_t evals = 0;
  refine(pc, height, evals);
  if (refineEvals) *refineEvals += evals;

  // Loops by following the successors.
  const std::size_t nv = pc.vertices.size();
  std::vector<char> seen(nv, 0);
  std::vector<SliceLoop> loops;
  const double dupTol = 1e-9 * g;
  for (std::size_t start = 0; start < nv; ++start) {
    if (seen[start] || pc.next[start] < 0) continue;
    std::vector<Eigen::Vector2d> pts;
    std::size_t at = start;
    bool closed = false;
    while (!seen[at]) {
      seen[at] = 1;
      const Eigen::Vector2d p = pc.vertices[at].at();
      if (pts.empty() || (p - pts.back()).norm() > dupTol) pts.push_back(p);
      const int nx = pc.next[at];
      if (nx < 0) break;
      at = static_cast<std::size_t>(nx);
      if (at == start) {
        closed = true;
        break;
      }
    }
    if (!closed) {
      layer.touchesBoundary = true;  // an open chain: cannot happen with a closed border; dropped
      continue;
    }
    while (pts.size() > 1 && (pts.front() - pts.back()).norm() <= dupTol) pts.pop_back();
    if (pts.size() < 3) continue;
    // Start at the lowest (u, v) vertex for a deterministic order.
    const auto first = std::min_element(pts.begin(), pts.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
      return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
    });
    std::rotate(pts.begin(), first, pts.end());
    SliceLoop loop;
    loop.points.resize(static_cast<Eigen::Index>(pts.size()), 2);
    for (std::size_t i = 0; i < pts.size(); ++i) loop.points.row(static_cast<Eigen::Index>(i)) = pts[i].transpose();
    loop.level = levels[static_cast<std::size_t>(pc.vertices[start].level)].value;
    loop.area = signedArea(loop.points);
    if (loop.area == 0.0) continue;
    loops.push_back(std::move(loop));
  }

  // Containment tree: the parent is the smallest loop that contains a vertex of the loop (loops do not
  // cross, so one vertex decides).
  const std::size_t nloops = loops.size();
  std::vector<Eigen::AlignedBox2d> box(nloops);
  for (std::size_t i = 0; i < nloops; ++i) {
    box[i] = Eigen::AlignedBox2d(loops[i].points.colwise().minCoeff().transpose(),
                                 loops[i].points.colwise().maxCoeff().transpose());
  }
  std::vector<int> parent(nloops, -1);
  for (std::size_t i = 0; i < nloops; ++i) {
    const double x = loops[i].points(0, 0), y = loops[i].points(0, 1);
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t j = 0; j < nloops; ++j) {
      if (j == i || std::abs(loops[j].area) <= std::abs(loops[i].area) || std::abs(loops[j].area) >= best) continue;
      if (!box[j].contains(box[i])) continue;
      if (pointInPolygon(loops[j].points, x, y)) {
        best = std::abs(loops[j].area);
        parent[i] = static_cast<int>(j);
      }
    }
  }
  // Depth-first order, siblings by their first vertex.
  std::vector<std::vector<int>> children(nloops + 1);
  for (std::size_t i = 0; i < nloops; ++i) {
    children[parent[i] < 0 ? nloops : static_cast<std::size_t>(parent[i])].push_back(static_cast<int>(i));
  }
  auto byFirst = [&](int a, int b) {
    const auto& pa = loops[static_cast<std::size_t>(a)].points;
    const auto& pb = loops[static_cast<std::size_t>(b)].points;
    return pa(0, 0) < pb(0, 0) || (pa(0, 0) == pb(0, 0) && pa(0, 1) < pb(0, 1));
  };
  for (auto& c : children) std::sort(c.begin(), c.end(), byFirst);
  std::vector<int> newIndex(nloops, -1);
  std::vector<std::pair<int, int>> stack;  // (old index, depth)
  for (auto it = children[nloops].rbegin(); it != children[nloops].rend(); ++it) stack.emplace_back(*it, 0);
  while (!stack.empty()) {
    const auto [i, depth] = stack.back();
    stack.pop_back();
    const auto ui = static_cast<std::size_t>(i);
    newIndex[ui] = static_cast<int>(layer.loops.size());
    SliceLoop l = std::move(loops[ui]);
    l.depth = depth;
    l.parent = parent[ui];  // remapped below
    layer.loops.push_back(std::move(l));
    for (auto it = children[ui].rbegin(); it != children[ui].rend(); ++it) stack.emplace_back(*it, depth + 1);
  }
  for (SliceLoop& l : layer.loops) {
    if (l.parent >= 0) l.parent = newIndex[static_cast<std::size_t>(l.parent)];
    layer.area += l.area;
  }

  // Thickness.
  if (options.layer > 0.0) {
    layer.thickness = options.layer;
    return layer;
  }
  const std::size_t nvert = layer.vertexCount();
  double tmin = std::numeric_limits<double>::infinity();
  if (nvert > 0) {
    Points q(static_cast<Eigen::Index>(nvert), 3);
    Eigen::Index row = 0;
    for (const SliceLoop& l : layer.loops) {
      for (Eigen::Index i = 0; i < l.points.rows(); ++i, ++row) {
        q(row, options.axis) = height;
        q(row, u) = l.points(i, 0);
        q(row, v) = l.points(i, 1);
      }
    }
    const auto batch = static_cast<Eigen::Index>(options.batchPoints);
    for (Eigen::Index b0 = 0; b0 < q.rows(); b0 += batch) {
      const Eigen::Index m = std::min(batch, q.rows() - b0);
      const FieldSamples s = eval(q.middleRows(b0, m), FieldDerivatives::Hessian);
      for (Eigen::Index i = 0; i < m; ++i) {
        const double t = vertexThickness(s.gradients.row(i).transpose(), s.hessians.row(i), options.axis, options.cusp,
                                         options.maxLayer, options.rule);
        tmin = std::min(tmin, t);
      }
    }
  }
  layer.rawThickness = tmin;
  layer.thickness = std::isfinite(tmin) ? std::clamp(tmin, options.minLayer, options.maxLayer) : options.maxLayer;
  return layer;
}

Slicer::Slicer(const Device& device, const ImplicitField& field, const SliceOptions& options)
    : impl_(std::make_unique<Impl>()) {
  impl_->setup(field.bounds(), field.offsets(), options);
  impl_->evaluator = std::make_unique<FieldEvaluator>(device, field, options.precision);
}

Slicer::Slicer(FieldFunction function, const Eigen::AlignedBox3d& bounds, std::vector<double> offsets,
               const SliceOptions& options)
    : impl_(std::make_unique<Impl>()) {
  if (!function) throw InvalidArgument("slice: no function to slice");
  impl_->setup(bounds, offsets, options);
  impl_->function = std::move(function);
}

Slicer::Slicer(Slicer&&) noexcept = default;
Slicer& Slicer::operator=(Slicer&&) noexcept = default;
Slicer::~Slicer() = default;

const SliceOptions& Slicer::options() const noexcept { return impl_->options; }
const std::vector<double>& Slicer::levels() const noexcept { return impl_->levelValues; }
const Eigen::AlignedBox3d& Slicer::bounds() const noexcept { return impl_->bounds; }

SliceLayer Slicer::layerAt(double height) const {
  if (!std::isfinite(height)) throw InvalidArgument("slice: the height " + num(height) + " is not finite");
  return impl_->layerAt(height, nullptr, nullptr);
}

SliceResult Slicer::run(Interrupter* interrupter) const {
  const auto t0 = Clock::now();
  const SliceOptions& o = impl_->options;
  SliceResult r;
  r.mode = o.mode;
  r.axis = o.axis;
  r.adaptive = o.layer == 0.0;
  r.rule = o.rule;
  r.cusp = o.cusp;
  r.minLayer = o.minLayer;
  r.maxLayer = o.maxLayer;
  r.layer = o.layer;
  r.grid = o.grid;
  r.levels = impl_->levelValues;
  r.bounds = impl_->bounds;
  r.start = o.start;
  r.end = o.end;
  const double span = std::max(o.end - o.start, 1e-300);
  const double step = r.adaptive ? o.minLayer : o.layer;
  const std::size_t cap = static_cast<std::size_t>(std::ceil(span / step)) + 2;
  double z = o.start;
  for (std::size_t i = 0; z < o.end; ++i) {
    if (i > cap) throw InvalidArgument("slice: more layers than the height range allows (internal error)");
    if (!r.adaptive) z = o.start + static_cast<double>(i) * o.layer;  // no accumulated rounding
    if (!(z < o.end)) break;
    SliceLayer layer = impl_->layerAt(z, &r.samples, &r.refineEvaluations);
    r.vertices += layer.vertexCount();
    const double t = layer.thickness;
    const std::size_t nloops = layer.loops.size();
    r.layers.push_back(std::move(layer));
    if (interrupter != nullptr) {
      const double fraction = std::min(1.0, (z + t - o.start) / span);
      std::ostringstream line;
      line << "  layer " << r.layers.size() << "  height " << std::setprecision(6) << z << "  thickness " << t
           << "  loops " << nloops << "  (" << std::setprecision(3) << 100.0 * fraction << "%)";
      interrupter->message(line.str());
      if (interrupter->wasInterrupted(static_cast<int>(std::lround(100.0 * fraction)))) {
        throw Cancelled("slice: cancelled after " + std::to_string(r.layers.size()) + " layers");
      }
    }
    z += t;
  }
  r.seconds = secondsSince(t0);
  return r;
}

SliceResult slice(const Device& device, const ImplicitField& field, const SliceOptions& options,
                  Interrupter* interrupter) {
  return Slicer(device, field, options).run(interrupter);
}

}  // namespace duplexfit
