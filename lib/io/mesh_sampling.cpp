// sampleMeshCloud: a triangle mesh as an oriented cloud (systematic area-proportional counts, a shifted R2
// sequence inside each face, exact face normals), with the checks of a mesh input (topology from
// analyzeTopology; the first offending faces, the optional re-orientation and the inside-out test here).
#include "duplexfit/mesh_sampling.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/timer.hpp"

namespace duplexfit {

namespace {

/// The largest number of samples any rule may ask for (48 bytes a point: about 5 GB).
constexpr double kMaxSamples = 1e8;

/// A well-mixed 64-bit hash of (seed, a, b) (the splitmix64 finaliser applied to a combination).
std::uint64_t mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// A uniform number in [0, 1) determined by (seed, a, b).
double uniform01(std::uint64_t seed, std::uint64_t a, std::uint64_t b) {
  const std::uint64_t h = mix(mix(mix(seed) ^ a) ^ (b * 0xd1b54a32d192ed03ULL));
  return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0);  // 53 bits / 2^53
}

std::string number(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

/// A directed face edge keyed by its undirected vertex pair (as analyzeTopology builds them).
struct HalfEdge {
  std::uint64_t key;
  std::uint32_t face;
  bool forward;  ///< traversed from the smaller to the larger index
};

/// The half-edges of the faces with three distinct indices, sorted by edge, then face.
std::vector<HalfEdge> sortedHalfEdges(const Mesh& mesh) {
  std::vector<HalfEdge> edges;
  edges.reserve(3 * static_cast<std::size_t>(mesh.faces.rows()));
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    const std::int32_t t[3] = {mesh.faces(f, 0), mesh.faces(f, 1), mesh.faces(f, 2)};
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) continue;
    for (int k = 0; k < 3; ++k) {
      const auto a = static_cast<std::uint32_t>(t[k]);
      const auto b = static_cast<std::uint32_t>(t[(k + 1) % 3]);
      const std::uint64_t lo = std::min(a, b), hi = std::max(a, b);
      edges.push_back({(lo << 32) | hi, static_cast<std::uint32_t>(f), a < b});
    }
  }
  std::sort(edges.begin(), edges.end(), [](const HalfEdge& x, const HalfEdge& y) {
    return x.key != y.key ? x.key < y.key : x.face < y.face;
  });
  return edges;
}

/// The first faces on a boundary, a non-manifold and an inconsistent edge (smallest face indices).
void findFirstFaces(const std::vector<HalfEdge>& edges, MeshSampleReport& r) {
  const auto lower = [](std::int64_t& slot, std::int64_t face) {
    if (slot < 0 || face < slot) slot = face;
  };
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i + 1;
    while (j < edges.size() && edges[j].key == edges[i].key) ++j;
    if (j - i == 1) {
      lower(r.firstBoundaryFace, edges[i].face);
    } else if (j - i > 2) {
      lower(r.firstNonManifoldFace, edges[i].face);
    } else if (edges[i].forward == edges[i + 1].forward) {
      const std::int64_t a = edges[i].face, b = edges[i + 1].face;  // a < b (sorted by face)
      if (r.firstInconsistentFaces[0] < 0 || a < r.firstInconsistentFaces[0] ||
          (a == r.firstInconsistentFaces[0] && b < r.firstInconsistentFaces[1])) {
        r.firstInconsistentFaces[0] = a;
        r.firstInconsistentFaces[1] = b;
      }
    }
    i = j;
  }
}

/// Which faces to flip so that the faces agree across every manifold edge they can: a breadth-first walk
/// over the manifold edges of each component; then each component keeps the orientation of the larger
/// part of its area (the fewest flipped by area).
std::vector<char> consistentFlips(const Mesh& mesh, const std::vector<HalfEdge>& edges,
                                  const std::vector<double>& area) {
  const auto nf = static_cast<std::size_t>(mesh.faces.rows());
  // Neighbours across manifold edges: (face, whether the pair traverses the edge in the same direction).
  std::vector<std::size_t> start(nf + 1, 0);
  std::vector<std::pair<std::uint32_t, std::uint32_t>> links;  // (f, g), both directions
  std::vector<char> same;
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i + 1;
    while (j < edges.size() && edges[j].key == edges[i].key) ++j;
    if (j - i == 2) {
      const bool s = edges[i].forward == edges[i + 1].forward;
      links.emplace_back(edges[i].face, edges[i + 1].face);
      same.push_back(s ? 1 : 0);
      links.emplace_back(edges[i + 1].face, edges[i].face);
      same.push_back(s ? 1 : 0);
    }
    i = j;
  }
  for (const auto& l : links) ++start[l.first + 1];
  for (std::size_t f = 0; f < nf; ++f) start[f + 1] += start[f];
  std::vector<std::uint32_t> neighbour(links.size());
  std::vector<char> neighbourSame(links.size());
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (std::size_t k = 0; k < links.size(); ++k) {
      const std::size_t at = fill[links[k].first]++;
      neighbour[at] = links[k].second;
      neighbourSame[at] = same[k];
    }
  }
  std::vector<char> flip(nf, 0), seen(nf, 0);
  std::vector<std::uint32_t> queue, component;
  for (std::size_t seed = 0; seed < nf; ++seed) {
    if (seen[seed]) continue;
    seen[seed] = 1;
    queue.assign(1, static_cast<std::uint32_t>(seed));
    component.clear();
    double flippedArea = 0.0, keptArea = 0.0;
    for (std::size_t q = 0; q < queue.size(); ++q) {
      const std::uint32_t f = queue[q];
      component.push_back(f);
      (flip[f] ? flippedArea : keptArea) += area[f];
      for (std::size_t k = start[f]; k < start[f + 1]; ++k) {
        const std::uint32_t g = neighbour[k];
        if (seen[g]) continue;  // a conflict here is a non-orientable surface: counted afterwards
        seen[g] = 1;
        // Same direction: one of the two must turn.
        flip[g] = static_cast<char>(neighbourSame[k] ? !flip[f] : flip[f]);
        queue.push_back(g);
      }
    }
    if (flippedArea > keptArea) {
      for (const std::uint32_t f : component) flip[f] = static_cast<char>(!flip[f]);
    }
  }
  return flip;
}

void checkOptions(const MeshSampleOptions& o, const std::string& source) {
  if (o.points > 0 && o.spacing != 0.0) {
    throw InvalidArgument(source + ": give the number of samples or their spacing, not both");
  }
  if (o.spacing != 0.0 && !(o.spacing > 0.0 && std::isfinite(o.spacing))) {
    throw InvalidArgument(source + ": the sample spacing must be a positive number (got " + number(o.spacing) + ")");
  }
  if (static_cast<double>(o.points) > kMaxSamples) {
    throw InvalidArgument(source + ": " + std::to_string(o.points) + " samples is more than the limit of 1e8");
  }
  if (!(o.defaultSpacingFraction > 0.0 && std::isfinite(o.defaultSpacingFraction))) {
    throw InvalidArgument(source + ": the default spacing fraction must be a positive number");
  }
  if (o.minPoints == 0 || o.minPoints > o.maxPoints || static_cast<double>(o.maxPoints) > kMaxSamples) {
    throw InvalidArgument(source + ": the default rule needs 0 < minPoints <= maxPoints <= 1e8");
  }
}

}  // namespace

const char* meshOrientationName(MeshOrientation orientation) noexcept {
  switch (orientation) {
    case MeshOrientation::Require:
      return "require";
    case MeshOrientation::Reorient:
      return "reorient";
    case MeshOrientation::Keep:
      return "keep";
  }
  return "?";
}

MeshSampleResult sampleMeshCloud(const Mesh& mesh, const MeshSampleOptions& options, const std::string& source) {
  const Timer timer;
  checkOptions(options, source);
  MeshSampleResult result;
  MeshSampleReport& r = result.report;
  r.source = source;
  r.orientation = options.orientation;
  const Eigen::Index nv = mesh.vertices.rows();
  const auto nf = static_cast<std::size_t>(mesh.faces.rows());
  if (nf == 0) {
    throw InvalidArgument(source + ": the mesh has no faces (" + std::to_string(nv) +
                          " vertices); a mesh input needs triangles to sample");
  }
  // Indices and the referenced vertices, named in the message.
  std::vector<char> used(static_cast<std::size_t>(nv), 0);
  for (std::size_t f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      const std::int32_t v = mesh.faces(static_cast<Eigen::Index>(f), k);
      if (v < 0 || v >= nv) {
        throw InvalidArgument(source + ": face " + std::to_string(f) + ": vertex index " + std::to_string(v) +
                              " out of range (the mesh has " + std::to_string(nv) + " vertices)");
      }
      used[static_cast<std::size_t>(v)] = 1;
    }
  }
  Eigen::AlignedBox3d box;
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (!used[static_cast<std::size_t>(v)]) continue;
    const Eigen::Vector3d p = mesh.vertices.row(v).transpose();
    if (!p.allFinite() || p.cwiseAbs().maxCoeff() > 1e64) {
      throw InvalidArgument(source + ": vertex " + std::to_string(v) + " has a non-finite or huge coordinate");
    }
    box.extend(p);
  }
  r.largestSide = box.sizes().maxCoeff();
  r.topology = analyzeTopology(mesh);

  // Areas; degenerate faces (repeated index, or zero area by validateMesh's rule) get none.
  std::vector<double> area(nf, 0.0);
  for (std::size_t f = 0; f < nf; ++f) {
    const auto row = static_cast<Eigen::Index>(f);
    const std::int32_t i = mesh.faces(row, 0), j = mesh.faces(row, 1), k = mesh.faces(row, 2);
    if (i == j || j == k || k == i) {
      ++r.degenerateFaces;
      continue;
    }
    const Eigen::Vector3d a = mesh.vertices.row(i).transpose(), b = mesh.vertices.row(j).transpose(),
                          c = mesh.vertices.row(k).transpose();
    const double twice = (b - a).cross(c - a).norm();
    const double longest2 = std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    if (!(twice > 1e-12 * longest2)) {
      ++r.degenerateFaces;
      continue;
    }
    area[f] = 0.5 * twice;
    r.area += area[f];
  }
  if (!(r.area > 0.0) || !std::isfinite(r.area)) {
    throw InvalidArgument(source + ": the mesh has zero area: all " + std::to_string(nf) +
                          " faces are degenerate (repeated or collinear corners)");
  }

  // Orientation: the first offending faces, then the policy.
  const std::vector<HalfEdge> edges = sortedHalfEdges(mesh);
  findFirstFaces(edges, r);
  const MeshTopology& t = r.topology;
  std::vector<char> flip(nf, 0);
  if (t.inconsistentEdges > 0) {
    const std::string what = std::to_string(t.inconsistentEdges) +
                             " edge(s) traversed in the same direction by both of their faces (first: faces " +
                             std::to_string(r.firstInconsistentFaces[0]) + " and " +
                             std::to_string(r.firstInconsistentFaces[1]) + ")";
    switch (options.orientation) {
      case MeshOrientation::Require:
        throw InvalidArgument(source + ": the mesh is not consistently oriented: " + what +
                              ", so its face normals disagree and cannot orient the fit; --mesh-reorient orients "
                              "the faces consistently (the larger part of each component by area decides), "
                              "--estimate-normals estimates the normals from the samples instead");
      case MeshOrientation::Reorient: {
        flip = consistentFlips(mesh, edges, area);
        Mesh turned = mesh;
        for (std::size_t f = 0; f < nf; ++f) {
          if (!flip[f]) continue;
          ++r.reorientedFaces;
          std::swap(turned.faces(static_cast<Eigen::Index>(f), 1), turned.faces(static_cast<Eigen::Index>(f), 2));
        }
        r.inconsistentAfter = analyzeTopology(turned).inconsistentEdges;
        r.signedVolume = signedVolume(turned);
        std::string line = source + ": the mesh was not consistently oriented (" + what + "): " +
                           std::to_string(r.reorientedFaces) + " face(s) flipped to agree with their neighbours";
        if (r.inconsistentAfter > 0) {
          line += "; " + std::to_string(r.inconsistentAfter) +
                  " edge(s) still disagree (a non-orientable surface: the normals there are unreliable)";
        }
        r.warnings.push_back(line);
        break;
      }
      case MeshOrientation::Keep:
        r.warnings.push_back(source + ": the mesh is not consistently oriented (" + what +
                             "): the faces are sampled as they are");
        break;
    }
  }
  if (options.orientation != MeshOrientation::Reorient || t.inconsistentEdges == 0) r.signedVolume = signedVolume(mesh);

  if (t.boundaryEdges > 0 || t.nonManifoldEdges > 0) {
    std::string line = source + ": the mesh is ";
    if (t.boundaryEdges > 0) {
      line += "open: " + std::to_string(t.boundaryEdges) + " boundary edge(s) (first at face " +
              std::to_string(r.firstBoundaryFace) + ")";
    }
    if (t.nonManifoldEdges > 0) {
      line += std::string(t.boundaryEdges > 0 ? ", and " : "") + "not 2-manifold: " +
              std::to_string(t.nonManifoldEdges) + " edge(s) shared by more than two faces (first at face " +
              std::to_string(r.firstNonManifoldFace) + ")";
    }
    if (options.strict) throw InvalidArgument(line + " (--strict)");
    line += t.boundaryEdges > 0 ? "; the fit closes its holes smoothly, a guess of the surface there"
                                : "; the fit follows the samples of every sheet";
    r.warnings.push_back(line);
  }
  if (r.degenerateFaces > 0) {
    r.warnings.push_back(source + ": " + std::to_string(r.degenerateFaces) +
                         " degenerate face(s) (repeated or collinear corners) dropped: they get no samples");
  }
  r.flipped = r.signedVolume < 0.0;
  if (r.flipped) {
    r.warnings.push_back(source + ": the mesh is inside out (signed volume " + number(r.signedVolume) +
                         " < 0): every normal is flipped to point outward");
  }

  // The number of samples.
  double wanted = 0.0;
  if (options.points > 0) {
    r.densityRule = "points";
    wanted = static_cast<double>(options.points);
  } else {
    const bool given = options.spacing > 0.0;
    r.densityRule = given ? "spacing" : "default";
    r.requestedSpacing = given ? options.spacing : options.defaultSpacingFraction * r.largestSide;
    // ⌈area / h²⌉, not lifted by a rounding error above an integer (6 / 0.05² is 2400, not 2401).
    const double exact = r.area / (r.requestedSpacing * r.requestedSpacing);
    wanted = std::ceil(exact * (1.0 - 1e-12));
    if (!given) {
      const double lo = static_cast<double>(options.minPoints), hi = static_cast<double>(options.maxPoints);
      if (!(wanted >= lo && wanted <= hi)) {
        r.clamped = true;
        const double raw = wanted;
        wanted = std::isfinite(wanted) ? std::clamp(wanted, lo, hi) : hi;
        r.warnings.push_back(source + ": the default density (spacing " + number(r.requestedSpacing) + ") asks for " +
                             number(raw) + " samples, clamped to " + number(wanted) +
                             " (--sample-points or --sample-spacing sets them)");
      }
    } else if (!(wanted <= kMaxSamples)) {
      throw InvalidArgument(source + ": spacing " + number(options.spacing) + " on an area of " + number(r.area) +
                            " asks for " + number(wanted) + " samples, more than the limit of 1e8");
    }
  }
  const auto total = static_cast<std::size_t>(wanted);
  // Positions and normals (48 bytes), the sample's face, the per-face tables and the cloud's copy later.
  requireMemory(options.limits, "mesh sampling", 100.0 * static_cast<double>(total) + 16.0 * static_cast<double>(nf),
                number(static_cast<double>(total)) + " samples of " + source,
                "use fewer --sample-points or a larger --sample-spacing");

  // Systematic sampling along the cumulative area: sample s sits at (s + u)·A/M, so face f gets
  // ⌊M·C_f/A + u⌋ − ⌊M·C_{f−1}/A + u⌋ samples (C: the cumulative area), M in all.
  std::vector<std::size_t> first(nf + 1, 0);
  {
    const double u = uniform01(options.seed, 0, 0);
    const double scale = wanted / r.area;
    double cumulative = 0.0;
    for (std::size_t f = 0; f < nf; ++f) {
      cumulative += area[f];
      const double upTo = std::floor(cumulative * scale + u);
      first[f + 1] = std::min(total, static_cast<std::size_t>(std::max(upTo, 0.0)));
      first[f + 1] = std::max(first[f + 1], first[f]);
    }
    first[nf] = total;  // rounding of the last partial sum
  }

  // Inside a face: the R2 sequence (Roberts; the plastic number g, steps 1/g and 1/g²) shifted by a random
  // vector, mapped area-uniformly onto the triangle by (u, v) → (1 − √u, √u(1 − v), √u·v).
  constexpr double g = 1.32471795724474602596;
  constexpr double a1 = 1.0 / g, a2 = 1.0 / (g * g);
  Points positions(static_cast<Eigen::Index>(total), 3), normals(static_cast<Eigen::Index>(total), 3);
  result.faces.resize(total);
  const double sign = r.flipped ? -1.0 : 1.0;
  for (std::size_t f = 0; f < nf; ++f) {
    if (first[f + 1] == first[f]) continue;
    const auto row = static_cast<Eigen::Index>(f);
    const Eigen::Vector3d a = mesh.vertices.row(mesh.faces(row, 0)).transpose();
    Eigen::Vector3d b = mesh.vertices.row(mesh.faces(row, 1)).transpose();
    Eigen::Vector3d c = mesh.vertices.row(mesh.faces(row, 2)).transpose();
    if (flip[f]) std::swap(b, c);
    const Eigen::Vector3d normal = sign * (b - a).cross(c - a).normalized();
    const double s1 = uniform01(options.seed, f + 1, 1), s2 = uniform01(options.seed, f + 1, 2);
    for (std::size_t s = first[f]; s < first[f + 1]; ++s) {
      const auto k = static_cast<double>(s - first[f]);
      const double x = s1 + k * a1, y = s2 + k * a2;
      const double uu = x - std::floor(x), vv = y - std::floor(y);
      const double root = std::sqrt(uu);
      const Eigen::Vector3d p = (1.0 - root) * a + root * (1.0 - vv) * b + root * vv * c;
      const auto out = static_cast<Eigen::Index>(s);
      positions.row(out) = p.transpose();
      normals.row(out) = normal.transpose();
      result.faces[s] = static_cast<std::int64_t>(f);
    }
  }
  result.points = PointSet(std::move(positions), std::move(normals));
  r.samples = total;
  r.spacing = total > 0 ? std::sqrt(r.area / static_cast<double>(total)) : 0.0;
  r.seconds = timer.seconds();
  return result;
}

}  // namespace duplexfit
