// Moving an extracted mesh onto its level set: Newton projection of the vertices, then longest-edge splits
// of the faces whose centre stays off it (docs/method.md §7, "Projection onto the level set").
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/measure.hpp"
#include "duplexfit/mesh_finish.hpp"
#include "newton.hpp"

namespace duplexfit {

namespace {

using Vec = Eigen::Vector3d;
using Tri = std::array<Index, 3>;

/// Newton steps of a projection: where |∇f| is small (a thin part of the solid) a path onto the level set
/// takes up to a dozen capped steps.
constexpr int kNewtonSteps = 20;

/// The mesh being moved and split: positions, faces, each face's extracted unit normal (zero for a face
/// extracted with no area) and vertex → faces (each face with a non-degenerate directed edge from it).
struct Work {
  std::vector<Vec> v;
  std::vector<Vec> extracted;  ///< each vertex on the extracted mesh (a split's: its edge's midpoint there)
  std::vector<Tri> f;
  std::vector<Vec> n0;
  std::vector<std::vector<Index>> vf;

  /// The face with the directed edge a → b, −1 when none has it or more than one does (not a consistently
  /// oriented manifold edge). Found among a's faces (about six), so no edge table is built: a hash map
  /// of the 3·#F directed edges took 3 s of fandisk_550k's offset mesh.
  Index edgeFace(Index a, Index b) const {
    Index found = -1;
    for (const Index face : vf[static_cast<std::size_t>(a)]) {
      const Tri& t = f[static_cast<std::size_t>(face)];
      for (int k = 0; k < 3; ++k) {
        if (t[static_cast<std::size_t>(k)] == a && t[static_cast<std::size_t>((k + 1) % 3)] == b) {
          if (found >= 0 && found != face) return -1;
          found = face;
        }
      }
    }
    return found;
  }
  Vec centre(Index face) const {
    const Tri& t = f[static_cast<std::size_t>(face)];
    return (v[static_cast<std::size_t>(t[0])] + v[static_cast<std::size_t>(t[1])] + v[static_cast<std::size_t>(t[2])]) / 3.0;
  }
};

void replaceFace(std::vector<Index>& list, Index from, Index to) {
  for (Index& x : list) {
    if (x == from) {
      x = to;
      return;
    }
  }
}

/// Whether triangle (q0, q1, q2) is acceptable after a move or a split: not float32-degenerate, within the
/// normal change of its extracted unit normal `ref` (zero: not checked), and not newly below minAngle
/// (`before()`: the smallest angle of the triangle it replaces, asked for only below minAngle).
template <typename Before>
bool triangleAcceptable(const Vec& q0, const Vec& q1, const Vec& q2, const Vec& ref, const Before& before,
                        double cosMax, double minAngle) {
  if (float32Degenerate(q0, q1, q2)) return false;
  const Vec n = (q1 - q0).cross(q2 - q0);
  if (ref.squaredNorm() > 0.0 && !(n.normalized().dot(ref) >= cosMax)) return false;
  if (!minAngleBelow(q0, q1, q2, minAngle)) return true;
  return !(minAngleDegrees(q0, q1, q2) < before());
}

/// Whether moving vertex `vertex` to p keeps every triangle around it acceptable.
bool moveAcceptable(const Work& w, Index vertex, const Vec& p, double cosMax, double minAngle) {
  for (const Index face : w.vf[static_cast<std::size_t>(vertex)]) {
    const Tri& t = w.f[static_cast<std::size_t>(face)];
    std::array<Vec, 3> now{}, moved{};
    for (int k = 0; k < 3; ++k) {
      now[static_cast<std::size_t>(k)] = w.v[static_cast<std::size_t>(t[static_cast<std::size_t>(k)])];
      moved[static_cast<std::size_t>(k)] = t[static_cast<std::size_t>(k)] == vertex ? p : now[static_cast<std::size_t>(k)];
    }
    const auto before = [&now] { return minAngleDegrees(now[0], now[1], now[2]); };
    if (!triangleAcceptable(moved[0], moved[1], moved[2], w.n0[static_cast<std::size_t>(face)], before, cosMax,
                            minAngle)) {
      return false;
    }
  }
  return true;
}

}  // namespace

ProjectResult projectToLevelSet(const FieldGradientSampler& sampler, const Mesh& mesh, double iso, double side,
                                const ProjectOptions& o) {
  const auto startTime = std::chrono::steady_clock::now();
  if (!(side > 0.0) || !std::isfinite(side)) throw InvalidArgument("projection onto the level set: side must be positive");
  if (!std::isfinite(iso)) throw InvalidArgument("projection onto the level set: the iso value must be finite");
  if (!(o.target >= 0.0) || !std::isfinite(o.target) || o.rounds < 0 || !(o.maxGrowth >= 1.0) ||
      !(o.maxMove >= 0.0) || !(o.maxNormalChange > 0.0 && o.maxNormalChange <= 180.0) ||
      !(o.minAngle >= 0.0 && o.minAngle < 60.0)) {
    throw InvalidArgument("projection onto the level set: an option is out of range (target >= 0, rounds >= 0, "
                          "growth >= 1, move >= 0, normal change in (0, 180], min angle in [0, 60))");
  }
  const auto nv = static_cast<std::size_t>(mesh.vertices.rows());
  const auto nf = static_cast<std::size_t>(mesh.faces.rows());
  if (nv > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max() / 2)) {
    throw InvalidArgument("projection onto the level set: too many vertices");
  }
  ProjectResult out;
  ProjectReport& rep = out.report;
  rep.applied = true;
  rep.verticesBefore = nv;
  rep.facesBefore = nf;

  Work w;
  w.v.resize(nv);
  for (std::size_t i = 0; i < nv; ++i) w.v[i] = mesh.vertices.row(static_cast<Eigen::Index>(i)).transpose();
  w.extracted = w.v;
  w.f.resize(nf);
  w.n0.resize(nf);
  w.vf.resize(nv);
  {
    // Each list reserved at the vertex's degree: one allocation a vertex, not the doubling's four.
    std::vector<int> degree(nv, 0);
    for (std::size_t i = 0; i < nf; ++i) {
      for (int k = 0; k < 3; ++k) {
        const Index x = mesh.faces(static_cast<Eigen::Index>(i), k);
        if (x >= 0 && static_cast<std::size_t>(x) < nv) ++degree[static_cast<std::size_t>(x)];
      }
    }
    for (std::size_t v = 0; v < nv; ++v) w.vf[v].reserve(static_cast<std::size_t>(degree[v]));
  }
  for (std::size_t i = 0; i < nf; ++i) {
    Tri t{};
    for (int k = 0; k < 3; ++k) {
      const Index x = mesh.faces(static_cast<Eigen::Index>(i), k);
      if (x < 0 || static_cast<std::size_t>(x) >= nv) {
        throw InvalidArgument("projection onto the level set: face " + std::to_string(i) + " has vertex index " +
                              std::to_string(x) + " outside [0, " + std::to_string(nv) + ")");
      }
      t[static_cast<std::size_t>(k)] = x;
    }
    w.f[i] = t;
    const Vec n = (w.v[static_cast<std::size_t>(t[1])] - w.v[static_cast<std::size_t>(t[0])])
                      .cross(w.v[static_cast<std::size_t>(t[2])] - w.v[static_cast<std::size_t>(t[0])]);
    w.n0[i] = n.squaredNorm() > 0.0 ? Vec(n.normalized()) : Vec::Zero();
    const auto face = static_cast<Index>(i);
    for (int k = 0; k < 3; ++k) {
      const Index a = t[static_cast<std::size_t>(k)], b = t[static_cast<std::size_t>((k + 1) % 3)];
      if (a == b) continue;
      w.vf[static_cast<std::size_t>(a)].push_back(face);
    }
  }

  const double cosMax = std::cos(o.maxNormalChange * M_PI / 180.0);
  const double maxMove = o.maxMove > 0.0 ? o.maxMove : HUGE_VAL;
  std::size_t faceLimit = static_cast<std::size_t>(std::ceil(o.maxGrowth * static_cast<double>(nf)));
  if (o.maxFaces > 0) faceLimit = std::min(faceLimit, std::max(o.maxFaces, nf));

  std::vector<char> converged;
  std::vector<double> rest, endFirstOrder;
  Eigen::VectorXd values;
  Points gradients, endGradients;
  // The first-order distance last evaluated at each vertex and face centre where it still stands (NaN: not
  // known), handed to the deviation measure (ProjectResult::known).
  const double unknown = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> knownVertex(nv, unknown), knownCentre(nf, unknown);
  // With estimateCentres: ∇f at each vertex where it is now (the vertex was evaluated there or its Newton
  // path ended there), zero where not known; the first round predicts most faces' centres from them.
  std::vector<Vec> vg;
  // Projects the listed vertices (in index order, each move checked against the positions so far).
  const auto project = [&](const std::vector<Index>& list) {
    std::vector<Index> go;
    if (list.empty()) return;
    Points q(static_cast<Eigen::Index>(list.size()), 3);
    for (std::size_t i = 0; i < list.size(); ++i) {
      q.row(static_cast<Eigen::Index>(i)) = w.v[static_cast<std::size_t>(list[i])].transpose();
    }
    sampler(q, values, gradients);
    if (values.size() != q.rows() || gradients.rows() != q.rows()) {
      throw InvalidArgument("projection onto the level set: the sampler returned the wrong number of values");
    }
    if (o.estimateCentres && vg.size() < w.v.size()) vg.resize(w.v.size(), Vec::Zero());
    std::vector<Eigen::Index> goRow;
    for (std::size_t i = 0; i < list.size(); ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      const auto v = static_cast<std::size_t>(list[i]);
      // |f − iso| / |∇f| here, −1 at a flat point (|∇f| < 1e-6).
      const double first = detail::firstOrderDistance(values[r], gradients.row(r), iso);
      knownVertex[v] = first;
      // Within 1e-5 of the side already (1% of the deviation target), or at a flat point: left where it is.
      const bool stays = first < 0.0 || first <= 1e-5 * side;
      if (o.estimateCentres) vg[v] = stays && first >= 0.0 ? Vec(gradients.row(r).transpose()) : Vec::Zero();
      if (stays) continue;
      go.push_back(list[i]);
      goRow.push_back(r);
    }
    if (go.empty()) return;
    const auto ng = static_cast<Eigen::Index>(go.size());
    Points x(ng, 3), startGradients(ng, 3);
    Eigen::VectorXd startValues(ng);
    for (Eigen::Index i = 0; i < ng; ++i) {
      x.row(i) = q.row(goRow[static_cast<std::size_t>(i)]);
      startValues[i] = values[goRow[static_cast<std::size_t>(i)]];
      startGradients.row(i) = gradients.row(goRow[static_cast<std::size_t>(i)]);
    }
    const detail::NewtonStart known{startValues, startGradients};
    detail::newtonPaths(sampler, x, iso, side, converged, rest, kNewtonSteps, &known,
                        o.estimateCentres ? &endGradients : nullptr, &endFirstOrder);
    for (std::size_t i = 0; i < go.size(); ++i) {
      const Vec p = x.row(static_cast<Eigen::Index>(i)).transpose();
      const Vec& now = w.v[static_cast<std::size_t>(go[i])];
      if (!converged[i] || (p - now).norm() > maxMove) {
        ++rep.notConverged;
        continue;
      }
      // The whole way when the triangles around allow it, else half or a quarter of it.
      bool placed = false;
      for (const double part : {1.0, 0.5, 0.25}) {
        const Vec to = now + part * (p - now);
        if (moveAcceptable(w, go[i], to, cosMax, o.minAngle)) {
          w.v[static_cast<std::size_t>(go[i])] = to;
          // Known where it stands only at the path's end itself (now + (p − now) is p but for a rounding).
          knownVertex[static_cast<std::size_t>(go[i])] = (to.array() == p.array()).all() ? endFirstOrder[i] : unknown;
          if (o.estimateCentres && part == 1.0) {
            vg[static_cast<std::size_t>(go[i])] = endGradients.row(static_cast<Eigen::Index>(i)).transpose();
          }
          placed = true;
          rep.partial += part < 1.0 ? 1 : 0;
          break;
        }
      }
      if (!placed) {
        ++rep.refused;
        continue;
      }
      ++rep.moved;
    }
  };

  std::vector<Index> candidates;
  candidates.reserve(nv);
  std::vector<char> onBoundary(nv, 0);
  if (o.keepBoundary) {
    for (std::size_t i = 0; i < nf; ++i) {
      const Tri& t = w.f[i];
      for (int k = 0; k < 3; ++k) {
        const Index a = t[static_cast<std::size_t>(k)], b = t[static_cast<std::size_t>((k + 1) % 3)];
        if (a != b && w.edgeFace(b, a) < 0) onBoundary[static_cast<std::size_t>(a)] = onBoundary[static_cast<std::size_t>(b)] = 1;
      }
    }
  }
  for (std::size_t i = 0; i < nv; ++i) {
    if (!onBoundary[i]) candidates.push_back(static_cast<Index>(i));
  }
  std::vector<Index> measure(nf);
  for (std::size_t i = 0; i < nf; ++i) measure[i] = static_cast<Index>(i);
  std::vector<int> touched(nf, -1);  // the round that last split the face
  std::vector<char> gaveUp(nf, 0);   // a split of the face was refused
  for (int round = 0;; ++round) {
    project(candidates);
    if (!(o.target > 0.0) || round == o.rounds || measure.empty()) break;
    // The faces' centres: first order, then the Newton path where that is beyond the target. In the first
    // round a face whose three vertices lie on the level set with known gradients is predicted instead:
    // projecting the centre c onto the tangent planes at the corners and averaging (Phong tessellation's
    // construction) moves it by d = -(1/3) sum ((c - v_k).n_k) n_k, which is twice the sagitta on a
    // sphere. A face with |d| within a quarter of the target (an eighth of it on a sphere) is not evaluated.
    // It cannot see detail smaller than the triangle (corners' tangent planes agree, the centre is off):
    // hence opt-in (docs/method.md §7 gives what it misses on fandisk_50k).
    std::vector<Index> evaluate;
    if (round == 0 && o.estimateCentres) {
      evaluate.reserve(measure.size());
      for (const Index face : measure) {
        const Tri& t = w.f[static_cast<std::size_t>(face)];
        bool known = true;
        for (const Index v : t) known = known && vg[static_cast<std::size_t>(v)].squaredNorm() > 0.0;
        if (known) {
          const Vec c = w.centre(face);
          Vec d = Vec::Zero();
          for (const Index v : t) {
            const Vec n = vg[static_cast<std::size_t>(v)].normalized();
            d -= (c - w.v[static_cast<std::size_t>(v)]).dot(n) * n;
          }
          if (d.norm() / 3.0 <= 0.25 * o.target) {
            ++rep.centresPredicted;
            continue;
          }
        }
        evaluate.push_back(face);
      }
    } else {
      evaluate = measure;
    }
    rep.centresEvaluated += evaluate.size();
    Points q(static_cast<Eigen::Index>(evaluate.size()), 3);
    for (std::size_t i = 0; i < evaluate.size(); ++i) q.row(static_cast<Eigen::Index>(i)) = w.centre(evaluate[i]).transpose();
    if (evaluate.empty()) break;  // every centre predicted within the target
    sampler(q, values, gradients);
    if (values.size() != q.rows() || gradients.rows() != q.rows()) {
      throw InvalidArgument("projection onto the level set: the sampler returned the wrong number of values");
    }
    std::vector<std::pair<double, Index>> marked;
    std::vector<Index> far;
    std::vector<double> farFirst;
    std::vector<Eigen::Index> farRow;
    for (std::size_t i = 0; i < evaluate.size(); ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      const double first = detail::firstOrderDistance(values[r], gradients.row(r), iso);
      knownCentre[static_cast<std::size_t>(evaluate[i])] = first;
      const double e = first < 0.0 ? HUGE_VAL : first;  // a flat centre (−1): marked
      if (e > o.target) {
        far.push_back(evaluate[i]);
        farFirst.push_back(e);
        farRow.push_back(r);
      }
    }
    if (!far.empty()) {
      const auto nfar = static_cast<Eigen::Index>(far.size());
      Points x(nfar, 3), start(nfar, 3), startGradients(nfar, 3);
      Eigen::VectorXd startValues(nfar);
      for (Eigen::Index i = 0; i < nfar; ++i) {
        const Eigen::Index r = farRow[static_cast<std::size_t>(i)];
        start.row(i) = q.row(r);
        startValues[i] = values[r];
        startGradients.row(i) = gradients.row(r);
      }
      x = start;
      const detail::NewtonStart known{startValues, startGradients};
      detail::newtonPaths(sampler, x, iso, side, converged, rest, kNewtonSteps, &known);
      for (std::size_t i = 0; i < far.size(); ++i) {
        const auto r = static_cast<Eigen::Index>(i);
        const double e = converged[i] ? (x.row(r) - start.row(r)).norm() + rest[i] : farFirst[i];
        if (e > o.target && !gaveUp[static_cast<std::size_t>(far[i])]) marked.emplace_back(e, far[i]);
      }
    }
    rep.markedLeft = marked.size();
    if (marked.empty()) break;
    // The farthest first, so that a face limit leaves the nearest ones.
    std::sort(marked.begin(), marked.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    // Choose disjoint splits: the longest edge a → b of each marked face (cyclic order, c the third corner)
    // and the triangle (b, a, d) across it.
    struct Split {
      Index face, other, a, b, c, d;
    };
    std::vector<Split> chosen;
    std::size_t planned = w.f.size();
    for (const auto& [dev, face] : marked) {
      (void)dev;
      if (planned + 2 > faceLimit) break;
      if (touched[static_cast<std::size_t>(face)] == round) continue;
      const Tri t = w.f[static_cast<std::size_t>(face)];
      int best = 0;
      double bestLength = -1.0;
      for (int k = 0; k < 3; ++k) {
        const Index from = t[static_cast<std::size_t>(k)], to = t[static_cast<std::size_t>((k + 1) % 3)];
        // With keepBoundary a boundary edge is never split: the longest of the others is.
        if (o.keepBoundary && w.edgeFace(to, from) < 0) continue;
        const double l = (w.v[static_cast<std::size_t>(to)] - w.v[static_cast<std::size_t>(from)]).squaredNorm();
        if (l > bestLength) {
          bestLength = l;
          best = k;
        }
      }
      if (bestLength < 0.0) continue;
      const Index a = t[static_cast<std::size_t>(best)], b = t[static_cast<std::size_t>((best + 1) % 3)],
                  c = t[static_cast<std::size_t>((best + 2) % 3)];
      const Index other = w.edgeFace(b, a);
      if (other < 0 || other == face || w.edgeFace(a, b) != face || touched[static_cast<std::size_t>(other)] == round) {
        continue;
      }
      const Tri& u = w.f[static_cast<std::size_t>(other)];
      Index d = -1;
      for (int k = 0; k < 3; ++k) {
        if (u[static_cast<std::size_t>(k)] != a && u[static_cast<std::size_t>(k)] != b) d = u[static_cast<std::size_t>(k)];
      }
      if (d < 0 || d == c) continue;  // (a, b, c) and (b, a, c): a two-triangle sheet, left alone
      touched[static_cast<std::size_t>(face)] = round;
      touched[static_cast<std::size_t>(other)] = round;
      chosen.push_back(Split{face, other, a, b, c, d});
      planned += 2;
    }
    // Each new vertex goes onto the level set before its split is made: the split is made only when the
    // four triangles around the projected vertex pass the move checks, so no vertex is left off the level
    // set (a face whose split is refused is not split again).
    Points x(static_cast<Eigen::Index>(chosen.size()), 3);
    for (std::size_t i = 0; i < chosen.size(); ++i) {
      x.row(static_cast<Eigen::Index>(i)) =
          0.5 * (w.v[static_cast<std::size_t>(chosen[i].a)] + w.v[static_cast<std::size_t>(chosen[i].b)]).transpose();
    }
    const Points mids = x;
    if (!chosen.empty()) detail::newtonPaths(sampler, x, iso, side, converged, rest, kNewtonSteps, nullptr, nullptr, &endFirstOrder);
    std::vector<Index> fresh;
    std::size_t splitsThisRound = 0;
    for (std::size_t i = 0; i < chosen.size(); ++i) {
      const auto [face, other, a, b, c, d] = chosen[i];
      const Vec p = x.row(static_cast<Eigen::Index>(i)).transpose();
      const auto giveUp = [&] {
        gaveUp[static_cast<std::size_t>(face)] = 1;
        touched[static_cast<std::size_t>(face)] = -1;
        touched[static_cast<std::size_t>(other)] = -1;
      };
      if (!converged[i] || (p - mids.row(static_cast<Eigen::Index>(i)).transpose()).norm() > maxMove) {
        ++rep.notConverged;
        giveUp();
        continue;
      }
      const Vec &va = w.v[static_cast<std::size_t>(a)], &vb = w.v[static_cast<std::size_t>(b)],
                &vc = w.v[static_cast<std::size_t>(c)], &vd = w.v[static_cast<std::size_t>(d)];
      const double angleFace = minAngleDegrees(va, vb, vc), angleOther = minAngleDegrees(vb, va, vd);
      const auto fits = [&](const Vec& q0, const Vec& q1, const Vec& q2, const Vec& ref, double parentAngle) {
        return triangleAcceptable(q0, q1, q2, ref, [parentAngle] { return parentAngle; }, cosMax, o.minAngle);
      };
      const Vec nFace = w.n0[static_cast<std::size_t>(face)], nOther = w.n0[static_cast<std::size_t>(other)];
      if (!fits(va, p, vc, nFace, angleFace) || !fits(p, vb, vc, nFace, angleFace) ||
          !fits(vb, p, vd, nOther, angleOther) || !fits(p, va, vd, nOther, angleOther)) {
        ++rep.refused;
        giveUp();
        continue;
      }
      const auto m = static_cast<Index>(w.v.size());
      const auto g1 = static_cast<Index>(w.f.size()), g2 = g1 + 1;
      w.v.push_back(p);
      knownVertex.push_back(endFirstOrder[i]);
      w.extracted.push_back(0.5 * (w.extracted[static_cast<std::size_t>(a)] + w.extracted[static_cast<std::size_t>(b)]));
      ++rep.moved;
      // (a, b, c) → (a, m, c) + (m, b, c); (b, a, d) → (b, m, d) + (m, a, d): orientations kept.
      w.f[static_cast<std::size_t>(face)] = Tri{a, m, c};
      w.f[static_cast<std::size_t>(other)] = Tri{b, m, d};
      w.f.push_back(Tri{m, b, c});
      w.f.push_back(Tri{m, a, d});
      w.n0.push_back(nFace);
      w.n0.push_back(nOther);
      touched.resize(w.f.size(), -1);
      gaveUp.resize(w.f.size(), 0);
      knownCentre[static_cast<std::size_t>(face)] = knownCentre[static_cast<std::size_t>(other)] = unknown;
      knownCentre.resize(w.f.size(), unknown);
      for (const Index y : {face, other, g1, g2}) touched[static_cast<std::size_t>(y)] = round;
      w.vf.push_back({face, g1, other, g2});
      replaceFace(w.vf[static_cast<std::size_t>(b)], face, g1);
      replaceFace(w.vf[static_cast<std::size_t>(a)], other, g2);
      w.vf[static_cast<std::size_t>(c)].push_back(g1);
      w.vf[static_cast<std::size_t>(d)].push_back(g2);
      fresh.push_back(m);
      ++splitsThisRound;
    }
    rep.splits += splitsThisRound;
    if (splitsThisRound == 0) break;
    ++rep.rounds;
    rep.markedLeft = marked.size() > splitsThisRound ? marked.size() - splitsThisRound : 0;
    // Next round: the faces around the new vertices (already on the level set) and the marked faces left.
    candidates.clear();
    std::vector<char> seen(w.f.size(), 0);
    measure.clear();
    for (const auto& [dev, face] : marked) {  // marked faces left unsplit this round (a neighbour was split)
      (void)dev;
      if (touched[static_cast<std::size_t>(face)] != round && !gaveUp[static_cast<std::size_t>(face)] &&
          !seen[static_cast<std::size_t>(face)]) {
        seen[static_cast<std::size_t>(face)] = 1;
        measure.push_back(face);
      }
    }
    for (const Index m : fresh) {
      for (const Index face : w.vf[static_cast<std::size_t>(m)]) {
        if (!seen[static_cast<std::size_t>(face)]) {
          seen[static_cast<std::size_t>(face)] = 1;
          measure.push_back(face);
        }
      }
    }
    std::sort(measure.begin(), measure.end());
  }

  out.mesh.faces.resize(static_cast<Eigen::Index>(w.f.size()), 3);
  for (std::size_t i = 0; i < w.f.size(); ++i) {
    for (int k = 0; k < 3; ++k) out.mesh.faces(static_cast<Eigen::Index>(i), k) = w.f[i][static_cast<std::size_t>(k)];
  }
  const auto write = [&] {
    out.mesh.vertices.resize(static_cast<Eigen::Index>(w.v.size()), 3);
    for (std::size_t i = 0; i < w.v.size(); ++i) out.mesh.vertices.row(static_cast<Eigen::Index>(i)) = w.v[i].transpose();
  };
  write();
  if (o.undoSelfIntersections && w.v.size() > 0) {
    // Moves in a sub-cell feature can make two sheets cross. The vertices of every intersecting or
    // float32-degenerate triangle go back to where the extraction put them (on its triangles, for the
    // splits' vertices: a split of a flat triangle is flat), with a ring of neighbours that widens each
    // round; at worst every vertex goes back, which is the extracted surface.
    CheckOptions co;
    co.listedPairs = std::numeric_limits<std::size_t>::max();
    co.limits = o.limits;
    std::vector<char> back(w.v.size(), 0);
    std::size_t reverted = 0;
    // A pair can only start (or keep) intersecting when one of its faces has a vertex that moved since.
    // So round 0 asks about the faces with a vertex away from where the extraction put it (a pair of faces
    // neither of which moved crosses on the extracted surface itself, which no undo changes), and each
    // later round about the faces around the vertices the round before moved back (every pair of theirs,
    // against the whole mesh). The faces of the pairs found and of the later rounds are asked about once
    // more at the end: the pairs left with a face that moved or moved back. (Asking round 0 about every
    // face would count the extracted surface's own pairs too, but only 27% of fandisk_550k's zero-level
    // vertices move: its projection took 4.7 -> 7.3 s.)
    std::vector<std::int64_t> asked;
    for (std::size_t face = 0; face < w.f.size(); ++face) {
      for (const Index vtx : w.f[face]) {
        if (w.v[static_cast<std::size_t>(vtx)] != w.extracted[static_cast<std::size_t>(vtx)]) {
          asked.push_back(static_cast<std::int64_t>(face));
          break;
        }
      }
    }
    std::vector<std::int64_t> again;  // the faces of the pairs found and around what moved back
    for (int round = 0; round < 12 && !asked.empty(); ++round) {
      const SelfIntersections c = findSelfIntersections(out.mesh, co, &asked);
      if (round == 0) rep.selfIntersectionsFound = c.count;
      std::vector<Index> seeds;
      for (const auto& [x, y] : c.pairs) {
        again.push_back(x);
        again.push_back(y);
        for (const std::int64_t face : {x, y}) {
          for (const Index vtx : w.f[static_cast<std::size_t>(face)]) seeds.push_back(vtx);
        }
      }
      const auto degenerate = [&](std::size_t face) {
        const Tri& t = w.f[face];
        if (float32Degenerate(w.v[static_cast<std::size_t>(t[0])], w.v[static_cast<std::size_t>(t[1])],
                              w.v[static_cast<std::size_t>(t[2])])) {
          for (const Index vtx : t) seeds.push_back(vtx);
        }
      };
      for (const std::int64_t face : asked) degenerate(static_cast<std::size_t>(face));
      if (seeds.empty()) break;
      if (reverted == w.v.size()) break;  // the extracted surface itself (its own crossings are not ours)
      const bool all = round == 11;
      std::vector<Index> ring = seeds;
      for (int grow = 0; grow < round && !all; ++grow) {  // round r: the seeds and r rings around them
        std::vector<Index> next = ring;
        for (const Index vtx : ring) {
          for (const Index face : w.vf[static_cast<std::size_t>(vtx)]) {
            for (const Index u : w.f[static_cast<std::size_t>(face)]) next.push_back(u);
          }
        }
        std::sort(next.begin(), next.end());
        next.erase(std::unique(next.begin(), next.end()), next.end());
        ring = std::move(next);
      }
      if (all) {
        ring.resize(w.v.size());
        for (std::size_t i = 0; i < w.v.size(); ++i) ring[i] = static_cast<Index>(i);
      }
      asked.clear();
      for (const Index vtx : ring) {
        if (back[static_cast<std::size_t>(vtx)]) continue;
        back[static_cast<std::size_t>(vtx)] = 1;
        w.v[static_cast<std::size_t>(vtx)] = w.extracted[static_cast<std::size_t>(vtx)];
        ++reverted;
        for (const Index face : w.vf[static_cast<std::size_t>(vtx)]) asked.push_back(face);
      }
      // Nothing moved back: what is left crosses on the extracted surface itself.
      if (asked.empty()) break;
      std::sort(asked.begin(), asked.end());
      asked.erase(std::unique(asked.begin(), asked.end()), asked.end());
      again.insert(again.end(), asked.begin(), asked.end());
      write();
    }
    rep.reverted = reverted;
    rep.selfIntersectionsChecked = true;
    if (!again.empty()) {
      std::sort(again.begin(), again.end());
      again.erase(std::unique(again.begin(), again.end()), again.end());
      rep.selfIntersectionsLeft = findSelfIntersections(out.mesh, co, &again).count;
    }
    // What moved back stands where nothing was evaluated (nor do the centres of its faces).
    if (reverted > 0) {
      for (std::size_t v = 0; v < w.v.size(); ++v) {
        if (back[v]) knownVertex[v] = unknown;
      }
      for (std::size_t face = 0; face < w.f.size(); ++face) {
        for (const Index vtx : w.f[face]) {
          if (back[static_cast<std::size_t>(vtx)]) knownCentre[face] = unknown;
        }
      }
    }
  }
  out.known.vertices = std::move(knownVertex);
  out.known.centres = std::move(knownCentre);
  rep.verticesAfter = w.v.size();
  rep.facesAfter = w.f.size();
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - startTime).count();
  return out;
}

}  // namespace duplexfit
