// The pipelines' last step on each level set's mesh: cleaning, optional simplification, and the mesh's
// deviation from the level set, |f − iso| / |∇f| at the vertices and face centres (docs/method.md §7).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <string>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/measure.hpp"
#include "duplexfit/mesh_finish.hpp"
#include "newton.hpp"
#include "parallel/workers.hpp"
#include "splice.hpp"

namespace duplexfit {

namespace {

/// The first-order distances of `queries` (left at −1 where |∇f| is flat).
void firstOrder(const FieldGradientSampler& sampler, const Points& queries, double iso, double* out) {
  Eigen::VectorXd values;
  Points gradients;
  sampler(queries, values, gradients);
  if (values.size() != queries.rows() || gradients.rows() != queries.rows()) {
    throw InvalidArgument("level-set deviation: the sampler returned the wrong number of values");
  }
  for (Eigen::Index i = 0; i < queries.rows(); ++i) out[i] = detail::firstOrderDistance(values[i], gradients.row(i), iso);
}

/// f and ∇f through a field's evaluator.
FieldGradientSampler gradientSampler(const FieldEvaluator& evaluator) {
  return [&evaluator](const Points& q, Eigen::VectorXd& values, Points& gradients) {
    FieldSamples s = evaluator.evaluate(q, FieldDerivatives::Gradient);
    values = std::move(s.values);
    gradients = std::move(s.gradients);
  };
}

}  // namespace

void detail::newtonPaths(const FieldGradientSampler& sampler, Points& x, double iso, double side,
                         std::vector<char>& converged, std::vector<double>& rest, int steps,
                         const NewtonStart* start, Points* endGradients, std::vector<double>* endFirstOrder) {
  const Eigen::Index total = x.rows();
  if (endGradients) *endGradients = Points::Zero(total, 3);
  if (endFirstOrder) endFirstOrder->assign(static_cast<std::size_t>(total), std::numeric_limits<double>::quiet_NaN());
  converged.assign(static_cast<std::size_t>(total), 0);
  rest.assign(static_cast<std::size_t>(total), 0.0);
  std::vector<Eigen::Index> active(static_cast<std::size_t>(total));
  for (Eigen::Index i = 0; i < total; ++i) active[static_cast<std::size_t>(i)] = i;
  Points at = x;  // the positions of the active paths, in the order of `active`
  Eigen::VectorXd values;
  Points gradients;
  // Each step evaluates only the paths that have not converged yet (most take two or three steps).
  for (int step = 0; step <= steps && !active.empty(); ++step) {
    const auto n = static_cast<Eigen::Index>(active.size());
    if (step == 0 && start) {
      values = start->values;
      gradients = start->gradients;
    } else {
      sampler(at, values, gradients);
    }
    if (values.size() != n || gradients.rows() != n) {
      throw InvalidArgument("level-set deviation: the sampler returned the wrong number of values");
    }
    Eigen::Index kept = 0;
    for (Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Index id = active[static_cast<std::size_t>(i)];
      const Eigen::RowVector3d g = gradients.row(i);
      const double g2 = g.squaredNorm();
      const double remaining = g2 > 0.0 ? std::abs(values[i] - iso) / std::sqrt(g2) : HUGE_VAL;
      x.row(id) = at.row(i);
      if (endFirstOrder) (*endFirstOrder)[static_cast<std::size_t>(id)] = firstOrderDistance(values[i], g, iso);
      // Converged (to float32 noise in f, or to a negligible first-order rest).
      if (remaining <= 1e-5 * side || std::abs(values[i] - iso) <= 1e-6 * side) {
        converged[static_cast<std::size_t>(id)] = 1;
        rest[static_cast<std::size_t>(id)] = std::min(remaining, 1e-5 * side);
        if (endGradients) endGradients->row(id) = g;
        continue;
      }
      if (step == steps || !(g2 > 0.0)) continue;  // not converged
      Eigen::RowVector3d move = -(values[i] - iso) / g2 * g;
      const double len = move.norm(), cap = 0.01 * side;
      if (len > cap) move *= cap / len;
      active[static_cast<std::size_t>(kept)] = id;
      at.row(kept) = at.row(i) + move;
      ++kept;
    }
    active.resize(static_cast<std::size_t>(kept));
    at.conservativeResize(kept, 3);
  }
}

LevelSetDeviation levelSetDeviation(const FieldGradientSampler& sampler, const Mesh& mesh, double iso, double side,
                                    std::size_t maxSamples, const KnownFirstOrder* known) {
  const auto startTime = std::chrono::steady_clock::now();
  LevelSetDeviation d;
  d.side = side;
  d.limit = 1e-3 * side;
  const Eigen::Index nv = mesh.vertices.rows(), nf = mesh.faces.rows();
  if (nf > 0) validateMesh(mesh, "level-set deviation");  // indices in range, finite vertices
  const Eigen::Index all = nv + nf;
  d.candidates = static_cast<std::size_t>(all);
  // Candidate s: vertex s (s < nv) or the centre of face s − nv.
  const auto point = [&](Eigen::Index s) -> Eigen::RowVector3d {
    if (s < nv) return mesh.vertices.row(s);
    const Eigen::Index f = s - nv;
    return (mesh.vertices.row(mesh.faces(f, 0)) + mesh.vertices.row(mesh.faces(f, 1)) +
            mesh.vertices.row(mesh.faces(f, 2))) /
           3.0;
  };
  // The first-order distance of candidate s where `known` has it (NaN: not known).
  const bool knownVertices = known && known->vertices.size() == static_cast<std::size_t>(nv);
  const bool knownCentres = known && known->centres.size() == static_cast<std::size_t>(nf);
  const double unknown = std::numeric_limits<double>::quiet_NaN();
  const auto knownAt = [&](Eigen::Index s) {
    if (s < nv) return knownVertices ? known->vertices[static_cast<std::size_t>(s)] : unknown;
    return knownCentres ? known->centres[static_cast<std::size_t>(s - nv)] : unknown;
  };
  // The distances of the listed candidates: first order (evaluated where not known), then a Newton path
  // where that is not small.
  constexpr Eigen::Index kChunk = Eigen::Index{1} << 20;
  const auto measure = [&](const std::vector<Eigen::Index>& ids) {
    std::vector<double> e(ids.size());
    std::vector<std::size_t> ask;  // the places in ids of the candidates evaluated
    ask.reserve(ids.size());
    for (std::size_t s = 0; s < ids.size(); ++s) {
      const double k = knownAt(ids[s]);
      if (std::isnan(k)) {
        ask.push_back(s);
      } else {
        e[s] = k;
      }
    }
    const auto total = static_cast<Eigen::Index>(ask.size());
    Points queries;
    std::vector<double> got;
    for (Eigen::Index begin = 0; begin < total; begin += kChunk) {
      const Eigen::Index end = std::min(total, begin + kChunk);
      queries.resize(end - begin, 3);
      for (Eigen::Index s = begin; s < end; ++s) queries.row(s - begin) = point(ids[ask[static_cast<std::size_t>(s)]]);
      got.resize(static_cast<std::size_t>(end - begin));
      firstOrder(sampler, queries, iso, got.data());
      for (Eigen::Index s = begin; s < end; ++s) e[ask[static_cast<std::size_t>(s)]] = got[static_cast<std::size_t>(s - begin)];
    }
    std::vector<std::size_t> refine;
    for (std::size_t s = 0; s < e.size(); ++s) {
      if (e[s] > 0.25 * d.limit) refine.push_back(s);
    }
    std::vector<char> converged;
    std::vector<double> rest;
    for (std::size_t begin = 0; begin < refine.size(); begin += static_cast<std::size_t>(kChunk)) {
      const std::size_t end = std::min(refine.size(), begin + static_cast<std::size_t>(kChunk));
      const auto n = static_cast<Eigen::Index>(end - begin);
      Points start(n, 3);
      for (Eigen::Index i = 0; i < n; ++i) start.row(i) = point(ids[refine[begin + static_cast<std::size_t>(i)]]);
      Points x = start;
      detail::newtonPaths(sampler, x, iso, side, converged, rest);
      for (Eigen::Index i = 0; i < n; ++i) {
        if (!converged[static_cast<std::size_t>(i)]) continue;  // not converged: the first-order value stays
        e[refine[begin + static_cast<std::size_t>(i)]] = (x.row(i) - start.row(i)).norm() + rest[static_cast<std::size_t>(i)];
        ++d.refinedSamples;
      }
    }
    return e;
  };
  // Above maxSamples, an evenly strided subset of the vertices and face centres (deterministic).
  const Eigen::Index total =
      maxSamples > 0 && static_cast<std::size_t>(all) > maxSamples ? static_cast<Eigen::Index>(maxSamples) : all;
  std::vector<Eigen::Index> ids(static_cast<std::size_t>(total));
  for (Eigen::Index picked = 0; picked < total; ++picked) {
    ids[static_cast<std::size_t>(picked)] =
        total == all ? picked : static_cast<Eigen::Index>((static_cast<long double>(picked) * all) / total);
  }
  // Where a measured sample (id) lies beyond the limit or half of it, and the maximum.
  const auto note = [&](double v, Eigen::Index id) {
    if (v > d.limit && d.aboveLimitAt.size() < LevelSetDeviation::kAboveLimitAt) {
      d.aboveLimitAt.push_back(point(id).transpose());
    }
    if (v > 0.5 * d.limit && d.nearLimitAt.size() < LevelSetDeviation::kAboveLimitAt) {
      d.nearLimitAt.push_back(point(id).transpose());
    }
    if (v > d.max) {
      d.max = v;
      d.maxAt = point(id).transpose();
    }
  };
  const std::vector<double> e = measure(ids);
  double sum = 0.0, sum2 = 0.0;
  std::vector<double> kept;
  kept.reserve(e.size());
  for (std::size_t s = 0; s < e.size(); ++s) {
    const double v = e[s];
    if (v < 0.0) {
      ++d.flatSamples;
      continue;
    }
    kept.push_back(v);
    sum += v;
    sum2 += v * v;
    d.aboveLimit += v > d.limit ? 1 : 0;
    note(v, ids[s]);
  }
  d.samples = kept.size();
  if (d.samples > 0) {
    d.mean = sum / static_cast<double>(d.samples);
    d.rms = std::sqrt(sum2 / static_cast<double>(d.samples));
    const auto rank = [&](double q) {
      const auto k = std::min(kept.size() - 1, static_cast<std::size_t>(std::ceil(q * static_cast<double>(kept.size()))) - 1);
      std::nth_element(kept.begin(), kept.begin() + static_cast<std::ptrdiff_t>(k), kept.end());
      return kept[k];
    };
    d.p999 = rank(0.999);
    d.p99 = rank(0.99);
  }
  // A stride finds the spread but rarely the largest deviation, which sits in a small region (a thin
  // fin, a neck): every vertex and face centre within kRings rings of a sample farther than an eighth of
  // the limit is measured too (at most maxSamples more, the worst samples' regions first), for the max.
  if (total < all && nf > 0) {
    constexpr int kRings = 4;
    // Seeds: the stride's samples beyond an eighth of the limit (a quarter missed part of igea_72k's
    // offset neck, which a second neck-pass round then had to find); the flood goes on from those beyond
    // a quarter.
    constexpr double kFloodFrom = 0.125;
    std::vector<std::size_t> bad;
    for (std::size_t s = 0; s < e.size(); ++s) {
      if (e[s] > kFloodFrom * d.limit) bad.push_back(s);
    }
    std::sort(bad.begin(), bad.end(), [&e](std::size_t a, std::size_t b) { return e[a] > e[b]; });
    if (!bad.empty()) {
      // Vertex → faces (compressed rows).
      std::vector<Eigen::Index> offset(static_cast<std::size_t>(nv) + 1, 0), vf(static_cast<std::size_t>(3 * nf));
      for (Eigen::Index f = 0; f < nf; ++f) {
        for (int k = 0; k < 3; ++k) ++offset[static_cast<std::size_t>(mesh.faces(f, k)) + 1];
      }
      for (std::size_t v = 0; v < static_cast<std::size_t>(nv); ++v) offset[v + 1] += offset[v];
      std::vector<Eigen::Index> fill(offset.begin(), offset.end() - 1);
      for (Eigen::Index f = 0; f < nf; ++f) {
        for (int k = 0; k < 3; ++k) vf[static_cast<std::size_t>(fill[static_cast<std::size_t>(mesh.faces(f, k))]++)] = f;
      }
      std::vector<char> taken(static_cast<std::size_t>(all), 0);
      for (const Eigen::Index s : ids) taken[static_cast<std::size_t>(s)] = 1;
      std::vector<std::uint32_t> stamp(static_cast<std::size_t>(nv), 0);
      std::uint32_t current = 0;
      std::vector<Eigen::Index> local;
      const auto take = [&](Eigen::Index s) {
        if (!taken[static_cast<std::size_t>(s)]) {
          taken[static_cast<std::size_t>(s)] = 1;
          local.push_back(s);
        }
      };
      // Flooded from the seeds (sample ids), kRings rings each; then again from the flooded samples that
      // are beyond a quarter of the limit, so that the whole of a neck or fin is measured, not only the
      // rings around the stride's samples that happened to land on it.
      std::vector<Eigen::Index> seeds;
      for (const std::size_t bs : bad) seeds.push_back(ids[bs]);
      while (!seeds.empty() && local.size() < maxSamples) {
        const std::size_t from = local.size();
        for (const Eigen::Index s : seeds) {
          if (local.size() >= maxSamples) break;
          ++current;  // each seed's rings are its own (a seed inside an earlier flood still reaches past it)
          std::vector<Eigen::Index> ring;
          if (s < nv) {
            ring.push_back(s);
          } else {
            for (int k = 0; k < 3; ++k) ring.push_back(mesh.faces(s - nv, k));
          }
          for (int r = 0; r <= kRings && !ring.empty(); ++r) {
            std::vector<Eigen::Index> next;
            for (const Eigen::Index v : ring) {
              if (stamp[static_cast<std::size_t>(v)] == current) continue;
              stamp[static_cast<std::size_t>(v)] = current;
              take(v);
              for (Eigen::Index j = offset[static_cast<std::size_t>(v)]; j < offset[static_cast<std::size_t>(v) + 1]; ++j) {
                const Eigen::Index f = vf[static_cast<std::size_t>(j)];
                take(nv + f);
                if (r < kRings) {
                  for (int k = 0; k < 3; ++k) next.push_back(mesh.faces(f, k));
                }
              }
            }
            ring = std::move(next);
          }
        }
        if (local.size() > maxSamples) local.resize(maxSamples);
        const std::vector<Eigen::Index> batch(local.begin() + static_cast<std::ptrdiff_t>(from), local.end());
        const std::vector<double> le = measure(batch);
        std::vector<std::pair<double, Eigen::Index>> worse;
        for (std::size_t i = 0; i < le.size(); ++i) {
          note(le[i], batch[i]);
          if (le[i] > 0.25 * d.limit) worse.emplace_back(le[i], batch[i]);
        }
        std::sort(worse.begin(), worse.end(), [](const auto& x, const auto& y) { return x.first > y.first; });
        seeds.clear();
        for (const auto& w : worse) seeds.push_back(w.second);
      }
      d.localSamples = local.size();
    }
  }
  d.relativeMax = side > 0.0 ? d.max / side : 0.0;
  d.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - startTime).count();
  return d;
}

LevelSetDeviation levelSetDeviation(const FieldEvaluator& evaluator, const ImplicitField& field, const Mesh& mesh,
                                    double iso, std::size_t maxSamples, const KnownFirstOrder* known) {
  const FieldGradientSampler sampler = gradientSampler(evaluator);
  return levelSetDeviation(sampler, mesh, iso, field.bounds().sizes().maxCoeff(), maxSamples, known);
}

void validateFinishOptions(const MeshFinishOptions& options) {
  if (!(options.collapseFraction >= 0.0 && options.collapseFraction <= 0.5)) {
    throw InvalidArgument("mesh cleaning: the collapse fraction must be in [0, 0.5] (of the grid cell)");
  }
  if (!(options.simplify.maxError >= 0.0) || !std::isfinite(options.simplify.maxError)) {
    throw InvalidArgument("simplification: the error bound (--max-error) must be a finite number >= 0");
  }
  if (!(options.projectTarget >= 0.0) || !std::isfinite(options.projectTarget)) {
    throw InvalidArgument("projection onto the level set: the target must be a finite fraction >= 0 of the side");
  }
  if ((options.simplify.maxTriangles > 0 || options.simplify.maxError > 0.0) && !simplificationAvailable()) {
    throw InvalidArgument("mesh simplification (--max-triangles, --max-error) needs meshoptimizer, and this build "
                          "of duplexfit has none (install libmeshoptimizer-dev and configure again)");
  }
}

namespace {

/// The counts of a second cleaning added to the first's; the result's statistics from the second.
void addClean(CleanReport& into, const CleanReport& more) {
  into.collapses += more.collapses;
  into.refusedTopology += more.refusedTopology;
  into.refusedGeometry += more.refusedGeometry;
  into.refusedCrossing += more.refusedCrossing;
  into.flips += more.flips;
  into.refusedFlips += more.refusedFlips;
  into.verticesAfter = more.verticesAfter;
  into.facesAfter = more.facesAfter;
  into.float32DegenerateAfter = more.float32DegenerateAfter;
  into.sliversAfter = more.sliversAfter;
  into.minAngleAfter = more.minAngleAfter;
  into.shortestEdgeAfter = more.shortestEdgeAfter;
  into.seconds += more.seconds;
}

}  // namespace

FieldGradientSampler detail::fieldGradientSampler(const FieldEvaluator& evaluator) { return gradientSampler(evaluator); }

CleanOptions detail::finishCleanOptions(const MeshFinishOptions& options, double cell) {
  CleanOptions clean;
  clean.collapseLength = options.collapseFraction * cell;
  return clean;
}

ProjectOptions detail::finishProjectOptions(const MeshFinishOptions& options, double side, double cell) {
  ProjectOptions po;
  po.target = options.projectTarget * side;
  po.maxMove = 3.0 * cell;
  po.maxFaces = options.simplify.maxTriangles;
  po.estimateCentres = options.predictCentres;
  return po;
}

FinishResult finishSurfaces(const FieldEvaluator& evaluator, const ImplicitField& field, std::vector<Mesh> meshes,
                            const std::vector<double>& isoValues, double cell, const MeshFinishOptions& options,
                            Interrupter* interrupter) {
  const auto start = std::chrono::steady_clock::now();
  validateFinishOptions(options);
  if (meshes.size() != isoValues.size()) {
    throw InvalidArgument("finishSurfaces: " + std::to_string(meshes.size()) + " meshes but " +
                          std::to_string(isoValues.size()) + " iso values");
  }
  if (!(cell > 0.0) || !std::isfinite(cell)) throw InvalidArgument("finishSurfaces: the cell must be positive");
  const CleanOptions clean = detail::finishCleanOptions(options, cell);
  const FieldGradientSampler sampler = gradientSampler(evaluator);
  const std::size_t n = meshes.size();
  FinishResult out;
  if (n == 0) return out;
  out.meshes.resize(n);
  out.reports.resize(n);
  // One mesh: nothing in it depends on another mesh, so several run at once (each on its own host thread;
  // the field evaluations take turns on the device).
  const auto finishOne = [&](std::size_t i) {
    const auto t = std::chrono::steady_clock::now();
    MeshFinishReport rep;
    Mesh mesh = std::move(meshes[i]);
    if (mesh.faces.rows() == 0) {  // nothing extracted at this level: nothing to clean or measure
      out.meshes[i] = std::move(mesh);
      out.reports[i] = rep;
      return;
    }
    if (options.clean) {
      CleanResult c = cleanMesh(mesh, clean);
      mesh = std::move(c.mesh);
      rep.clean = c.report;
    }
    SimplifyResult s = simplifyMesh(mesh, options.simplify);
    rep.simplify = s.report;
    if (s.report.applied && s.report.facesAfter != s.report.facesBefore) {
      mesh = std::move(s.mesh);
      if (options.clean) {
        CleanResult c = cleanMesh(mesh, clean);
        mesh = std::move(c.mesh);
        addClean(rep.clean, c.report);
      }
    }
    KnownFirstOrder known;  // what the projection evaluated where its vertices and faces stand
    if (options.project) {
      const double side = field.bounds().sizes().maxCoeff();
      const ProjectOptions po = detail::finishProjectOptions(options, side, cell);
      ProjectResult p = projectToLevelSet(sampler, mesh, isoValues[i], side, po);
      mesh = std::move(p.mesh);
      rep.project = p.report;
      known = std::move(p.known);
    }
    if (options.measureDeviation) {
      rep.deviation = levelSetDeviation(evaluator, field, mesh, isoValues[i], options.deviationSamples, &known);
      rep.deviationMeasured = true;
    }
    rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
    out.meshes[i] = std::move(mesh);
    out.reports[i] = rep;
  };
  const std::size_t workers = detail::workersFor(options.concurrentMeshes, n);
  // The meshes are taken in order by the workers; only this thread polls the interrupter (the caller's
  // object need not be thread-safe), before it takes each of its meshes.
  std::atomic<std::size_t> next{0};
  std::atomic<bool> stop{false};
  bool cancelled = false;
  std::vector<std::exception_ptr> errors(n);
  const auto work = [&](bool polls) {
    for (;;) {
      if (polls && interrupter && interrupter->wasInterrupted(static_cast<int>(100 * std::min(next.load(), n) / n))) {
        cancelled = true;
        stop.store(true);
        return;
      }
      const std::size_t i = next.fetch_add(1);
      if (i >= n || stop.load()) return;
      try {
        finishOne(i);
      } catch (...) {
        errors[i] = std::current_exception();
        stop.store(true);
      }
    }
  };
  detail::runOnWorkers(workers, work);
  for (const std::exception_ptr& e : errors) {
    if (e) std::rethrow_exception(e);
  }
  if (cancelled) throw Cancelled("cancelled while finishing the meshes");
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace duplexfit
