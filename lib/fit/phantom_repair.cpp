// Phantom repair (see include/duplexfit/phantom_repair.hpp and docs/method.md, "Phantom repair").
#include "duplexfit/phantom_repair.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>


#include "duplexfit/error.hpp"
#include "duplexfit/linalg.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/self_check.hpp"
#include "duplexfit/wendland.hpp"
#include "duplexfit/winding.hpp"
#include "fit/anchors.hpp"
#include "spatial/disk_distance.hpp"
#include "surfaces/newton.hpp"
#include "surfaces/splice.hpp"

namespace duplexfit {

namespace {

Points normalised(const Points& x, const Normalization& n) {
  return (n.scale * (x.rowwise() - n.centre.transpose())).eval();  // as fit() normalises its input
}

Points stack(const std::vector<Eigen::Vector3d>& rows) {
  Points p(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t i = 0; i < rows.size(); ++i) p.row(static_cast<Eigen::Index>(i)) = rows[i].transpose();
  return p;
}

/// The grid nodes of spacing h over `box` (normalised units), at most maxNodes (else none).
std::vector<Eigen::Vector3d> gridNodes(const Eigen::AlignedBox3d& box, double h, std::size_t maxNodes) {
  std::vector<Eigen::Vector3d> nodes;
  Eigen::Array3i n;
  std::size_t total = 1;
  for (int a = 0; a < 3; ++a) {
    n[a] = 1 + static_cast<int>(std::ceil(box.sizes()[a] / h));
    total *= static_cast<std::size_t>(n[a]);
  }
  if (total > maxNodes) return nodes;
  nodes.reserve(total);
  for (int k = 0; k < n[2]; ++k) {
    for (int j = 0; j < n[1]; ++j) {
      for (int i = 0; i < n[0]; ++i) nodes.push_back(box.min() + h * Eigen::Vector3d(i, j, k));
    }
  }
  return nodes;
}

}  // namespace

PhantomRepairResult repairPhantoms(const Device& device, Precision precision, const ImplicitField& field,
                                   const FieldEvaluator& evaluator, const Points& points, const Points& outwardNormals,
                                   const std::vector<Mesh>& meshes, const std::vector<double>& isos,
                                   const std::vector<EmptyComponent>& candidates, const PhantomRepairOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (meshes.empty() || meshes.size() != isos.size() || isos[0] != 0.0) {
    throw InvalidArgument("phantom repair: need the zero-level mesh first and one iso value per mesh");
  }
  if (points.rows() != outwardNormals.rows()) {
    throw InvalidArgument("phantom repair: " + std::to_string(points.rows()) + " points but " +
                          std::to_string(outwardNormals.rows()) + " normals");
  }
  if (field.levels().empty()) throw InvalidArgument("phantom repair: the field has no levels");
  if (!(options.anchorSpacing > 0.0) || !(options.keepRadius > 0.0) || !(options.minDistanceFraction > 0.0) ||
      !(options.maxChange > 0.0) || !(options.boxMargin >= 0.0) || !(options.offsetClearance >= 0.0)) {
    throw InvalidArgument("phantom repair: spacing, keep radius, distance fraction and change must be > 0, box "
                          "margin and offset clearance >= 0");
  }
  PhantomRepairResult out;
  PhantomRepairReport& rep = out.report;
  const auto finish = [&]() -> PhantomRepairResult {
    rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return std::move(out);
  };
  const std::vector<EmptyComponent>& empty = candidates;
  for (const EmptyComponent& e : empty) {
    for (const Index f : e.faceList) {
      if (f < 0 || f >= meshes[0].faces.rows()) {
        throw InvalidArgument("phantom repair: a candidate's face is not in the mesh");
      }
    }
  }
  rep.candidates = empty.size();
  if (empty.empty()) return finish();

  const Normalization& norm = field.normalization();
  const Points u = normalised(points, norm);
  const Points inward = -outwardNormals;
  const NeighborIndex index(u);
  const WindingNumber winding(u, outwardNormals, estimatePointAreas(u, outwardNormals, 12, index));
  const double sigma = field.levels().back().sigma;
  const double h = options.anchorSpacing * sigma;
  std::vector<double> offsets;  // normalised, > 0 inward
  for (std::size_t j = 1; j < isos.size(); ++j) offsets.push_back(isos[j] * norm.scale);

  // Anchors over each candidate; a candidate is a phantom when f has the wrong sign at one of them at least.
  struct Phantom {
    const EmptyComponent* component;
    Eigen::AlignedBox3d box;  // normalised, enlarged by h
    double minDistance;       // normalised
    double sign;              // the surroundings' sign: the anchors' targets'
    std::vector<Eigen::Vector3d> anchors;
    std::vector<double> targets;
    Points checked;           // check (b)'s grid nodes, found once (see below)
  };
  std::vector<Phantom> phantoms;
  for (const EmptyComponent& e : empty) {
    Eigen::AlignedBox3d box(norm.scale * (e.box.min() - norm.centre), norm.scale * (e.box.max() - norm.centre));
    box.min().array() -= options.boxMargin * sigma;
    box.max().array() += options.boxMargin * sigma;
    detail::AnchorOptions o;
    o.spacing = h;
    o.minDistance = options.minDistanceFraction * e.nearestInputPoint * norm.scale;
    o.maxDistance = 0.0;
    o.offsets = offsets;
    o.offsetClearance = options.offsetClearance * sigma;
    o.maxCells = std::size_t{1} << 21;
    const detail::Anchors a = detail::levelAnchors(box, u, inward, winding.areas(), index, winding, Points(0, 3), o);
    if (a.positions.rows() == 0) continue;
    const Eigen::VectorXd f = evaluator.evaluateNormalized(a.positions);
    // The surroundings' sign: that of the targets where f disagrees (the box holds solid beside the
    // phantom too, whose anchors agree).
    std::size_t wrong = 0;
    double sum = 0.0;
    for (Eigen::Index i = 0; i < f.size(); ++i) {
      if ((f[i] > 0.0) == (a.targets[i] > 0.0)) continue;
      ++wrong;
      sum += a.targets[i];
    }
    if (wrong == 0) {
      ++rep.notPhantom;
      continue;
    }
    Phantom p{&e, box, o.minDistance, sum > 0.0 ? 1.0 : -1.0, {}, {}, Points(0, 3)};
    // Check (b)'s nodes: a grid of h/2 over the box, those on the surroundings' side by the winding number
    // (as the anchors are classified) and as far from the samples: the box also holds solid and surface
    // beside the phantom. They do not depend on the field, so every round and attempt reuses them.
    const std::vector<Eigen::Vector3d> nodes = gridNodes(box, h / 2.0, std::size_t{1} << 21);
    if (nodes.empty()) {  // a box too large to check: left as it is
      ++rep.refusedPhantoms;
      if (rep.firstRefusal.empty()) rep.firstRefusal = "a phantom's box is too large to check";
      continue;
    }
    {
      const Points q = stack(nodes);
      const NeighborLists nearest = index.knnSearch(q, 1);
      const Eigen::VectorXd wn = winding.evaluate(q);
      std::vector<Eigen::Vector3d> kept;
      for (Eigen::Index i = 0; i < q.rows(); ++i) {
        const double d = nearest.distances[static_cast<std::size_t>(nearest.offsets[static_cast<std::size_t>(i)])];
        const bool surroundings = p.sign < 0.0 ? wn[i] < 0.25 : wn[i] > 0.75;
        if (surroundings && d >= p.minDistance) kept.push_back(nodes[static_cast<std::size_t>(i)]);
      }
      p.checked = stack(kept);
    }
    for (Eigen::Index i = 0; i < a.positions.rows(); ++i) {
      p.anchors.emplace_back(a.positions.row(i).transpose());
      p.targets.push_back(a.targets[i]);
    }
    phantoms.push_back(std::move(p));
  }
  if (phantoms.empty()) return finish();
  double side = 0.0;
  if (points.rows() > 0) side = (points.colwise().maxCoeff() - points.colwise().minCoeff()).maxCoeff();

  // An attempt repairs the active phantoms together; a failed check that points at one phantom (`blame`)
  // drops it and the others are tried again without it (a noisy bubble whose correction would move the
  // surface beside it must not keep a real phantom elsewhere). A failure that points at none refuses all.
  std::vector<char> active(phantoms.size(), 1);
  std::size_t activeCount = phantoms.size();
  int blame = -1;
  std::string why;
  Points c;
  std::size_t anchorCount = 0;
  std::optional<ImplicitField> repaired;
  std::shared_ptr<const FieldEvaluator> after;
  std::size_t repairedFaces = 0, offsetFaces = 0;  // reported when the repair is kept
  const auto attempt = [&]() -> bool {
    blame = -1;
    rep.maxChange = rep.maxDeviation = 0.0;
    out.moves.clear();
    out.removedFaces.clear();
    out.reextract.clear();
    std::vector<Eigen::Vector3d> anchorsNow;
    std::vector<double> targetsNow;
    std::vector<int> owner;  // the phantom of each anchor
    for (std::size_t k = 0; k < phantoms.size(); ++k) {
      if (!active[k]) continue;
      anchorsNow.insert(anchorsNow.end(), phantoms[k].anchors.begin(), phantoms[k].anchors.end());
      targetsNow.insert(targetsNow.end(), phantoms[k].targets.begin(), phantoms[k].targets.end());
      owner.insert(owner.end(), phantoms[k].anchors.size(), static_cast<int>(k));
    }
    // Up to three rounds: a node of the check (b) below where f keeps the phantom's sign becomes an anchor of
    // the next round (the grid's anchors skip candidates whose nearest samples' planes contradict the winding
    // number, and a pocket of the phantom can survive between them: armadillo_43k's foot).
    constexpr int kRounds = 3;
    for (int round = 0;; ++round) {
      anchorCount = anchorsNow.size();
      std::vector<Eigen::Vector3d> all = anchorsNow;
      // The points that keep f: input points near the anchors, their offset companions and off-surface points
      // on both sides (σ_M/10, as the fit's), unless within 1% of σ_M of an earlier centre. Each with the
      // value the fit gave it as target (0, δ_j, ±σ_M/10; see below).
      std::vector<double> fitTarget(anchorCount, 0.0);
      const NeighborLists near = index.radiusSearchUnsorted(stack(anchorsNow), options.keepRadius * sigma);
      std::vector<Index> kept(near.indices);
      std::sort(kept.begin(), kept.end());
      kept.erase(std::unique(kept.begin(), kept.end()), kept.end());
      for (const Index i : kept) {
        const Eigen::Vector3d p = u.row(i).transpose(), n = inward.row(i).transpose();
        all.push_back(p);
        fitTarget.push_back(0.0);
        for (const double d : offsets) {
          all.push_back(p + d * n);
          fitTarget.push_back(d);
        }
        if (n.squaredNorm() > 0.0) {
          all.push_back(p + 0.1 * sigma * n);
          all.push_back(p - 0.1 * sigma * n);
          fitTarget.push_back(0.1 * sigma);
          fitTarget.push_back(-0.1 * sigma);
        }
      }
      if (all.size() > options.maxCentres) {
        why = std::to_string(all.size()) + " correction centres (more than " + std::to_string(options.maxCentres) + ")";
        return false;
      }
      std::vector<double> keepTarget;  // of each distinct keep point
      {
        const Points stacked = stack(all);
        const NeighborLists close = NeighborIndex(stacked).radiusSearchUnsorted(stacked, 1e-2 * sigma);
        std::vector<Eigen::Vector3d> distinct(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(anchorCount));
        for (std::size_t i = anchorCount; i < all.size(); ++i) {
          bool earlier = false;
          for (auto k = close.offsets[i]; k < close.offsets[i + 1]; ++k) {
            earlier = earlier || static_cast<std::size_t>(close.indices[static_cast<std::size_t>(k)]) < i;
          }
          if (earlier) continue;
          distinct.push_back(all[i]);
          keepTarget.push_back(fitTarget[i]);
        }
        c = stack(distinct);
      }
      const auto nc = c.rows();

      // The correction g: g = target − f at the anchors, 0 at the keep points; Φ w = g (Wendland, support σ_M).
      // A keep point in a phantom's box where the phantom pulled f off the fit's target towards its own sign
      // (by more than σ_M/100 and more than the point's disk-soup distance to the samples differs from
      // |target|) gets it back: a void's pull on the offset companions beside it would otherwise stay as a
      // bump of the offset (the planted void of test_phantom_repair.cpp). A companion the fit rejected, in a
      // part thinner than 2δ, lies nearer the samples than δ and keeps f; so do the points outside the
      // boxes, whose f the fit may have left off such a target for its own reasons (restoring those too
      // moved wheel_29k's and armadillo_43k's surfaces beside their blobs beyond the bound at δ = 0.025).
      const Eigen::VectorXd fc = evaluator.evaluateNormalized(c);
      Eigen::VectorXd rhs = Eigen::VectorXd::Zero(nc);
      for (std::size_t i = 0; i < anchorCount; ++i) {
        rhs[static_cast<Eigen::Index>(i)] = targetsNow[i] - fc[static_cast<Eigen::Index>(i)];
      }
      {
        const double tolerance = 1e-2 * sigma;
        std::vector<Eigen::Index> off;
        for (Eigen::Index i = static_cast<Eigen::Index>(anchorCount); i < nc; ++i) {
          const double t = keepTarget[static_cast<std::size_t>(i) - anchorCount];
          if (!(std::abs(fc[i] - t) > tolerance)) continue;
          // Pulled towards a phantom's sign, within its box (a void pulls f down, a blob up).
          const Eigen::Vector3d x = c.row(i).transpose();
          bool pulled = false;
          for (std::size_t k = 0; k < phantoms.size() && !pulled; ++k) {
            pulled = active[k] && phantoms[k].box.contains(x) && (t - fc[i]) * phantoms[k].sign > 0.0;
          }
          if (pulled) off.push_back(i);
        }
        rep.restored = 0;
        if (!off.empty()) {
          Points q(static_cast<Eigen::Index>(off.size()), 3);
          for (std::size_t k = 0; k < off.size(); ++k) q.row(static_cast<Eigen::Index>(k)) = c.row(off[k]);
          const Eigen::VectorXd d = detail::diskSoupDistance(q, u, inward, winding.areas(), index);
          for (std::size_t k = 0; k < off.size(); ++k) {
            const Eigen::Index i = off[k];
            const double t = keepTarget[static_cast<std::size_t>(i) - anchorCount];
            if (!(std::abs(fc[i] - t) > std::abs(d[static_cast<Eigen::Index>(k)] - std::abs(t)) + tolerance)) continue;
            rhs[i] = t - fc[i];
            ++rep.restored;
          }
        }
      }
      // Conjugate gradients on the reference path in double with the fit's FSAI preconditioner: a few hundred
      // to a few thousand unknowns with some 200 couplings a row (anchors σ_M/4 apart), where a sparse LDLT's
      // fill-in took 0.3 s a round on armadillo_43k.
      const CsrMatrix a = assembleWendland(c, sigma);
      const Device host = Device::reference();
      const DeviceCsr da = DeviceCsr::upload(host, a, Precision::Double);
      const FsaiPreconditioner fsai(da, a);
      SolverOptions so;
      so.relativeTolerance = 1e-10;
      so.maxIterations = 5000;
      so.progressInterval = 0;
      DeviceVector dw = DeviceVector::upload(host, Eigen::VectorXd::Zero(nc), Precision::Double);
      const SolveStats solved = solveCg(da, DeviceVector::upload(host, rhs, Precision::Double), dw, so, &fsai);
      const Eigen::VectorXd w = solved.converged ? dw.download() : Eigen::VectorXd();
      rep.iterations += solved.iterations;
      if (w.size() != nc || !w.allFinite() || (a.multiply(w) - rhs).norm() > 1e-6 * std::max(1.0, rhs.norm())) {
        why = "the correction's system could not be solved";
        return false;
      }
      std::vector<FieldLevel> levels = field.levels();
      FieldLevel& finest = levels.back();
      Points grown(finest.centres.rows() + nc, 3);
      grown << finest.centres, c;
      Eigen::VectorXd weights(finest.weights.size() + nc);
      weights << finest.weights, w;
      finest.centres = std::move(grown);
      finest.weights = std::move(weights);
      repaired.emplace(field.normalization(), field.f0(), std::move(levels), field.offsets(), field.bounds());
      after = std::make_shared<const FieldEvaluator>(device, *repaired, precision);

      // Checks. (a) Every anchor's sign holds.
      const Eigen::VectorXd fa = after->evaluateNormalized(c.topRows(static_cast<Eigen::Index>(anchorCount)));
      for (std::size_t i = 0; i < anchorCount; ++i) {
        if ((fa[static_cast<Eigen::Index>(i)] > 0.0) != (targetsNow[i] > 0.0)) {
          why = "f does not take the anchors' signs";
          blame = owner[i];
          return false;
        }
      }
      // (b) f has the surroundings' sign at each phantom's check nodes (a grid of h/2 over its box, the
      // nodes on the surroundings' side away from the samples).
      std::vector<Eigen::Vector3d> wrong;
      std::vector<double> wrongSign;
      std::vector<int> wrongOwner;
      for (std::size_t k = 0; k < phantoms.size(); ++k) {
        if (!active[k]) continue;
        const Phantom& p = phantoms[k];
        const Eigen::VectorXd f = after->evaluateNormalized(p.checked);
        for (Eigen::Index i = 0; i < p.checked.rows(); ++i) {
          if (f[i] * p.sign > 0.0) continue;
          wrong.emplace_back(p.checked.row(i).transpose());
          wrongSign.push_back(p.sign);
          wrongOwner.push_back(static_cast<int>(k));
        }
      }
      rep.rounds = round + 1;
      if (wrong.empty()) break;
      if (round + 1 == kRounds) {
        why = "f keeps the phantom's sign at " + std::to_string(wrong.size()) + " nodes between the anchors";
        blame = wrongOwner.front();
        return false;
      }
      const Points q = stack(wrong);
      const Eigen::VectorXd d = detail::diskSoupDistance(q, u, inward, winding.areas(), index);
      for (std::size_t i = 0; i < wrong.size(); ++i) {
        anchorsNow.push_back(wrong[i]);
        targetsNow.push_back(wrongSign[i] * std::min(d[static_cast<Eigen::Index>(i)], 1.0));
        owner.push_back(wrongOwner[i]);
      }
    }
    std::vector<Index> removed;
    repairedFaces = offsetFaces = 0;
    for (std::size_t k = 0; k < phantoms.size(); ++k) {
      if (!active[k]) continue;
      removed.insert(removed.end(), phantoms[k].component->faceList.begin(), phantoms[k].component->faceList.end());
      repairedFaces += phantoms[k].component->faces;
    }
    std::sort(removed.begin(), removed.end());
    out.removedFaces.assign(meshes.size(), {});
    out.removedFaces[0] = removed;
    // An offset's components inside a phantom: a bump above δ_j holds a δ_j component too. One whose vertices
    // all lie in a phantom's box, where f − δ_j now has the surroundings' sign at every vertex, goes with it.
    for (std::size_t j = 1; j < meshes.size(); ++j) {
      const Mesh& mesh = meshes[j];
      if (mesh.faces.rows() == 0) continue;
      std::size_t count = 0;
      const std::vector<Index> labels = faceComponents(mesh, &count);
      const Points un = normalised(mesh.vertices, norm);
      std::vector<int> inside(count, -1);  // the phantom holding every vertex so far; −2: none does
      for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
        int& holder = inside[static_cast<std::size_t>(labels[static_cast<std::size_t>(f)])];
        for (int k = 0; k < 3 && holder != -2; ++k) {
          const Eigen::Vector3d x = un.row(mesh.faces(f, k)).transpose();
          if (holder >= 0 && phantoms[static_cast<std::size_t>(holder)].box.contains(x)) continue;
          holder = -2;
          for (std::size_t i = 0; i < phantoms.size(); ++i) {
            if (active[i] && phantoms[i].box.contains(x)) holder = static_cast<int>(i);
          }
        }
      }
      std::vector<Index> rows;
      std::vector<char> seen(static_cast<std::size_t>(mesh.vertices.rows()), 0);
      for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
        if (inside[static_cast<std::size_t>(labels[static_cast<std::size_t>(f)])] < 0) continue;
        for (int k = 0; k < 3; ++k) {
          const Index v = mesh.faces(f, k);
          if (!seen[static_cast<std::size_t>(v)]) rows.push_back(v);
          seen[static_cast<std::size_t>(v)] = 1;
        }
      }
      if (rows.empty()) continue;
      Points q(static_cast<Eigen::Index>(rows.size()), 3);
      for (std::size_t i = 0; i < rows.size(); ++i) q.row(static_cast<Eigen::Index>(i)) = mesh.vertices.row(rows[i]);
      const Eigen::VectorXd f = after->evaluate(q).values;
      std::vector<char> gone(count, 1);
      for (Eigen::Index f2 = 0; f2 < mesh.faces.rows(); ++f2) {
        const auto l = static_cast<std::size_t>(labels[static_cast<std::size_t>(f2)]);
        if (inside[l] < 0) continue;
        const double sign = phantoms[static_cast<std::size_t>(inside[l])].sign;
        for (int k = 0; k < 3; ++k) {
          const auto at = std::lower_bound(rows.begin(), rows.end(), mesh.faces(f2, k));
          const auto i = static_cast<Eigen::Index>(at - rows.begin());
          if (!((f[i] - isos[j]) * sign > 0.0)) gone[l] = 0;
        }
      }
      for (Eigen::Index f2 = 0; f2 < mesh.faces.rows(); ++f2) {
        const auto l = static_cast<std::size_t>(labels[static_cast<std::size_t>(f2)]);
        if (inside[l] >= 0 && gone[l]) out.removedFaces[j].push_back(static_cast<Index>(f2));
      }
      offsetFaces += out.removedFaces[j].size();
    }
    // (c) The other meshes' vertices within σ_M of a correction centre follow their level sets (the
    // finishing's Newton paths): the anchors' targets are the disk-soup distance, so the real surface beside a phantom moves
    // a little (wheel_29k: 0.001 of the side). The move is bounded, and no face around a moved vertex may
    // turn by more than 60 degrees.
    const NeighborIndex correction(c);
    const NeighborIndex anchorIndex(stack(anchorsNow));
    const FieldGradientSampler sampler = detail::fieldGradientSampler(*after);
    // The phantom whose anchor is nearest to a point (input units).
    const auto nearestOwner = [&](const Eigen::Vector3d& x) {
      Points q(1, 3);
      q.row(0) = norm.scale * (x - norm.centre).transpose();
      const NeighborLists n = anchorIndex.knnSearch(q, 1);
      return n.indices.empty() ? -1 : owner[static_cast<std::size_t>(n.indices[0])];
    };
    double largest = 0.0;
    Eigen::Vector3d largestAt = Eigen::Vector3d::Zero();
    const double tinyEdge = 1e-2 * sigma / norm.scale;
    out.moves.resize(meshes.size());
    out.reextract.assign(meshes.size(), {});
    rep.reextracted = 0;
    for (std::size_t j = 0; j < meshes.size(); ++j) {
      const Mesh& mesh = meshes[j];
      std::vector<char> skip(static_cast<std::size_t>(mesh.vertices.rows()), 0);
      for (const Index f : out.removedFaces[j]) {
        for (int k = 0; k < 3; ++k) skip[static_cast<std::size_t>(mesh.faces(f, k))] = 1;
      }
      const NeighborLists near = correction.nearestWithin(normalised(mesh.vertices, norm), sigma);
      std::vector<Index> rows;
      for (std::size_t v = 0; v < skip.size(); ++v) {
        if (!skip[v] && near.count(v) > 0) rows.push_back(static_cast<Index>(v));
      }
      if (rows.empty()) continue;
      Points q(static_cast<Eigen::Index>(rows.size()), 3);
      for (std::size_t i = 0; i < rows.size(); ++i) q.row(static_cast<Eigen::Index>(i)) = mesh.vertices.row(rows[i]);
      const Points before = q;
      std::vector<char> converged;
      std::vector<double> rest;
      detail::newtonPaths(sampler, q, isos[j], side, converged, rest);
      // With reextractMeshes, a mesh whose vertices cannot follow is handed back whole near the correction
      // (the moves of its other vertices still count towards the bound below).
      const auto handBack = [&] {
        out.reextract[j].reserve(rows.size());
        for (Eigen::Index i = 0; i < before.rows(); ++i) out.reextract[j].emplace_back(before.row(i).transpose());
        ++rep.reextracted;
      };
      bool lost = false;
      std::vector<Eigen::Index> far;  // the vertices moved beyond the bound
      for (Eigen::Index i = 0; i < q.rows(); ++i) {
        if (!converged[static_cast<std::size_t>(i)]) {
          if (options.reextractMeshes) {
            lost = true;
            continue;
          }
          why = "a vertex of surface " + std::to_string(j) + " beside the correction finds no level set";
          blame = nearestOwner(before.row(i).transpose());
          return false;
        }
        rep.maxDeviation = std::max(rep.maxDeviation, rest[static_cast<std::size_t>(i)]);
        const double moved = (q.row(i) - before.row(i)).norm();
        rep.maxChange = std::max(rep.maxChange, moved);
        if (moved > options.maxChange * side) far.push_back(i);
      }
      // A move beyond the bound is the level set's answer to the phantom's removal, not a distortion, when
      // the vertex ends on the level set where the mesh already was (within the bound of one of its
      // vertices: a part of the level set went with the phantom and what is left did not shift), or where
      // its distance from the samples (the disk-soup distance) is within the bound of |δ_j| or nearer to it
      // than where it started: the bound then holds against where the level set should be. A phantom
      // void's offset wraps it, and that lobe shrinks onto the offset sheet beside it or into a bump of it
      // (wheel_29k at δ = 0.01: 0.0137 from the samples, 0.013 before).
      if (!far.empty()) {
        Points from(static_cast<Eigen::Index>(far.size()), 3), to(static_cast<Eigen::Index>(far.size()), 3);
        for (std::size_t k = 0; k < far.size(); ++k) {
          from.row(static_cast<Eigen::Index>(k)) = before.row(far[k]);
          to.row(static_cast<Eigen::Index>(k)) = q.row(far[k]);
        }
        const NeighborLists nearest = NeighborIndex(mesh.vertices).knnSearch(to, 1);
        const Eigen::VectorXd d0 = detail::diskSoupDistance(normalised(from, norm), u, inward, winding.areas(), index);
        const Eigen::VectorXd d1 = detail::diskSoupDistance(normalised(to, norm), u, inward, winding.areas(), index);
        const double target = std::abs(isos[j]) * norm.scale;
        const double bound = options.maxChange * side * norm.scale;  // normalised, as d0 and d1
        for (std::size_t k = 0; k < far.size(); ++k) {
          const auto at = static_cast<std::size_t>(nearest.offsets[k]);
          if (nearest.offsets[k + 1] > nearest.offsets[k] && nearest.distances[at] <= options.maxChange * side) continue;
          const auto r = static_cast<Eigen::Index>(k);
          const double error = std::abs(d1[r] - target);
          if (error <= bound || error < std::abs(d0[r] - target)) continue;
          const double moved = (q.row(far[k]) - before.row(far[k])).norm();
          if (moved > largest) {
            largest = moved;
            largestAt = before.row(far[k]).transpose();
          }
        }
      }
      if (lost) {
        handBack();
        continue;
      }
      // The faces around the moved vertices keep their orientation.
      std::vector<Index> slot(skip.size(), -1);
      for (std::size_t i = 0; i < rows.size(); ++i) slot[static_cast<std::size_t>(rows[i])] = static_cast<Index>(i);
      const auto corner = [&](Eigen::Index f, int k, bool moved) -> Eigen::Vector3d {
        const Index v = mesh.faces(f, k);
        const Index i = moved ? slot[static_cast<std::size_t>(v)] : -1;
        return i >= 0 ? Eigen::Vector3d(q.row(i).transpose()) : Eigen::Vector3d(mesh.vertices.row(v).transpose());
      };
      for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
        bool touched = false;
        for (int k = 0; k < 3; ++k) touched = touched || slot[static_cast<std::size_t>(mesh.faces(f, k))] >= 0;
        if (!touched) continue;
        const Eigen::Vector3d p0 = corner(f, 0, false), p1 = corner(f, 1, false), p2 = corner(f, 2, false);
        const Eigen::Vector3d q0 = corner(f, 0, true);
        const Eigen::Vector3d n0 = (p1 - p0).cross(p2 - p0);
        const Eigen::Vector3d n1 = (corner(f, 1, true) - q0).cross(corner(f, 2, true) - q0);
        // A sliver's normal is ill-defined: it must only not flip; a face with some area must not turn by
        // more than 60 degrees. Faces under 1% of σ_M across (the extraction leaves some of 1e-6) are not
        // judged: a move of the solve's rounding turns them.
        const double longest =
            std::max(std::max((p1 - p0).squaredNorm(), (p2 - p0).squaredNorm()), (p2 - p1).squaredNorm());
        if (longest < tinyEdge * tinyEdge) continue;
        const bool sliver = n0.norm() < 1e-3 * longest;
        if (!(n1.dot(n0) > (sliver ? 0.0 : 0.5 * n1.norm() * n0.norm()))) {
          if (options.reextractMeshes) {
            lost = true;
            break;
          }
          why = "a face of surface " + std::to_string(j) + " beside the correction would turn";
          blame = nearestOwner(p0);
          return false;
        }
      }
      if (lost) {
        handBack();
        continue;
      }
      for (std::size_t i = 0; i < rows.size(); ++i) {
        out.moves[j].emplace_back(rows[i], Eigen::Vector3d(q.row(static_cast<Eigen::Index>(i)).transpose()));
      }
    }
    if (!(largest <= options.maxChange * side)) {
      why = "the correction moves another part of the meshes' level sets by " + std::to_string(largest) +
            " (more than " + std::to_string(options.maxChange * side) + ") away from its distance to the samples";
      blame = nearestOwner(largestAt);
      return false;
    }
    return true;
  };
  while (!attempt()) {
    if (blame < 0 || activeCount <= 1) {
      rep.refused = rep.refusedPhantoms > 0 ? "the last of " + std::to_string(rep.refusedPhantoms + 1) +
                                                   " phantoms: " + why
                                             : why;
      rep.refusedPhantoms += activeCount;
      out.moves.clear();
      out.removedFaces.clear();
      out.reextract.clear();
      rep.maxChange = rep.maxDeviation = 0.0;
      rep.reextracted = 0;
      return finish();
    }
    active[static_cast<std::size_t>(blame)] = 0;
    --activeCount;
    ++rep.refusedPhantoms;
    if (rep.firstRefusal.empty()) rep.firstRefusal = why;
  }
  rep.repaired = activeCount;
  rep.repairedFaces = repairedFaces;
  rep.offsetFaces = offsetFaces;
  rep.anchors = anchorCount;
  rep.keepPoints = static_cast<std::size_t>(c.rows()) - anchorCount;
  out.field = std::move(*repaired);
  out.evaluator = std::move(after);
  return finish();
}

}  // namespace duplexfit
