// ImplicitField: reference (brute-force) evaluation of f, ∇f, Hessian, and the versioned binary file
// format (docs/field-format.md): little-endian, FNV-1a 64 checksum over everything before it.
#include "duplexfit/field.hpp"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <istream>
#include <ostream>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "duplexfit/atomic_file.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/wendland.hpp"

namespace duplexfit {

namespace {

constexpr char kMagic[8] = {'D', 'P', 'X', 'F', 'I', 'E', 'L', 'D'};
constexpr std::uint32_t kVersion = 1;

// Contribution of one centre at offset u = x − c (normalised units) to f, ∇f and H (docs/method.md §6),
// written from φ, φ' and φ'' of the radius (chain rule: ∇φ = φ'/σ û, H = φ''/σ² ûûᵀ + φ'/(σρ)(I − ûûᵀ))
// rather than from the kernel's expanded form, so that it is an independent oracle for it.
struct Accumulator {
  double f = 0.0;
  Eigen::Vector3d g = Eigen::Vector3d::Zero();
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  void add(const Eigen::Vector3d& u, double w, double sigma, int order) {
    const double rho = u.norm();
    const double r = rho / sigma;
    if (r >= 1.0) return;
    f += w * wendland(r);
    if (order >= 1) {
      // φ'(r)/(σρ) = −20 (1 − r)³/σ² stays finite at ρ = 0, where ∇φ = 0.
      const double t = 1.0 - r;
      const double radial = -20.0 * t * t * t / (sigma * sigma);
      g += w * radial * u;
      if (order >= 2) {
        h += w * radial * Eigen::Matrix3d::Identity();
        if (rho > 0.0) {
          const Eigen::Vector3d n = u / rho;
          h += w * (wendlandSecondDerivative(r) / (sigma * sigma) - radial) * n * n.transpose();
        }
      }
    }
  }
};

Accumulator accumulate(const ImplicitField& field, const Eigen::Vector3d& x, int order) {
  const Normalization& n = field.normalization();
  const Eigen::Vector3d u = n.scale * (x - n.centre);
  Accumulator acc;
  acc.f = field.f0();
  for (const FieldLevel& level : field.levels()) {
    for (Eigen::Index j = 0; j < level.centres.rows(); ++j) {
      acc.add(u - level.centres.row(j).transpose(), level.weights[j], level.sigma, order);
    }
  }
  return acc;
}

// Little-endian binary writer and reader with the FNV-1a 64 checksum of the bytes before it.
/// FNV-1a 64 of `n` bytes, continuing from `hash`.
std::uint64_t fnv1a(std::uint64_t hash, const unsigned char* b, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) hash = (hash ^ b[i]) * 1099511628211ull;
  return hash;
}
constexpr std::uint64_t kFnvBasis = 1469598103934665603ull;

/// Little-endian writer into one buffer of the file's exact size (the checksum is taken over the buffer
/// once at the end): fandisk_550k's 104 MB field went through an ostringstream eight bytes at a time,
/// hashed byte by byte on the way, then was copied out of it (0.72 s of the fit's 1.5 s of writing).
class Writer {
 public:
  explicit Writer(std::size_t size) : buffer_(size) {}
  void bytes(const void* p, std::size_t n) {
    if (n > buffer_.size() - at_) throw std::logic_error("field file: the writer's size estimate is short");
    std::memcpy(buffer_.data() + at_, p, n);
    at_ += n;
  }
  void u32(std::uint32_t v) {
    unsigned char b[4];
    for (int i = 0; i < 4; ++i) b[i] = static_cast<unsigned char>(v >> (8 * i));
    bytes(b, 4);
  }
  void u64(std::uint64_t v) {
    unsigned char b[8];
    for (int i = 0; i < 8; ++i) b[i] = static_cast<unsigned char>(v >> (8 * i));
    bytes(b, 8);
  }
  void f64(double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, 8);
    u64(bits);
  }
  /// Appends the checksum of everything written so far; the buffer is then complete.
  std::vector<unsigned char> finish() {
    u64(fnv1a(kFnvBasis, buffer_.data(), at_));
    if (at_ != buffer_.size()) throw std::logic_error("field file: the writer's size estimate is long");
    return std::move(buffer_);
  }

 private:
  std::vector<unsigned char> buffer_;
  std::size_t at_ = 0;
};

class Reader {
 public:
  Reader(std::istream& in, std::string source) : in_(in), source_(std::move(source)) {}
  void bytes(void* p, std::size_t n, const char* what) {
    in_.read(static_cast<char*>(p), static_cast<std::streamsize>(n));
    if (static_cast<std::size_t>(in_.gcount()) != n) {
      throw IoError(source_ + ": truncated field file: cannot read " + what + " at byte " + std::to_string(offset_));
    }
    hash_ = fnv1a(hash_, static_cast<const unsigned char*>(p), n);
    offset_ += n;
  }
  std::uint32_t u32(const char* what) {
    unsigned char b[4];
    bytes(b, 4, what);
    std::uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(b[i]) << (8 * i);
    return v;
  }
  std::uint64_t u64(const char* what) {
    unsigned char b[8];
    bytes(b, 8, what);
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(b[i]) << (8 * i);
    return v;
  }
  double f64(const char* what) {
    const std::uint64_t bits = u64(what);
    double v;
    std::memcpy(&v, &bits, 8);
    if (!std::isfinite(v)) fail(std::string(what) + " is not finite");
    return v;
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw IoError(source_ + ": corrupt field file: " + what + " (byte " + std::to_string(offset_) + ")");
  }
  std::uint64_t hash() const { return hash_; }
  std::size_t offset() const { return offset_; }

 private:
  std::istream& in_;
  std::string source_;
  std::uint64_t hash_ = kFnvBasis;
  std::size_t offset_ = 0;
};

}  // namespace

ImplicitField::ImplicitField(Normalization normalization, double f0, std::vector<FieldLevel> levels,
                             std::vector<double> offsets, Eigen::AlignedBox3d worldBounds)
    : normalization_(std::move(normalization)),
      f0_(f0),
      levels_(std::move(levels)),
      offsets_(std::move(offsets)),
      bounds_(worldBounds) {
  if (!(normalization_.scale > 0.0) || !std::isfinite(normalization_.scale)) {
    throw InvalidArgument("ImplicitField: the normalisation scale must be positive and finite");
  }
  for (std::size_t k = 0; k < levels_.size(); ++k) {
    const FieldLevel& l = levels_[k];
    if (!(l.sigma > 0.0) || l.centres.rows() != l.weights.size()) {
      throw InvalidArgument("ImplicitField: level " + std::to_string(k + 1) +
                            " needs sigma > 0 and one weight per centre");
    }
  }
}

std::size_t ImplicitField::centreCount() const noexcept {
  std::size_t n = 0;
  for (const FieldLevel& l : levels_) n += static_cast<std::size_t>(l.centres.rows());
  return n;
}

double ImplicitField::value(const Eigen::Vector3d& x) const {
  return accumulate(*this, x, 0).f / normalization_.scale;
}

Eigen::Vector3d ImplicitField::gradient(const Eigen::Vector3d& x) const {
  return accumulate(*this, x, 1).g;  // d(f_n/s)/dx = (1/s)·∇_u f_n · s
}

Eigen::Matrix3d ImplicitField::hessian(const Eigen::Vector3d& x) const {
  return accumulate(*this, x, 2).h * normalization_.scale;
}

FieldSamples ImplicitField::evaluate(const Device& device, const Points& queries, FieldDerivatives derivatives,
                                     Precision precision) const {
  return FieldEvaluator(device, *this, precision).evaluate(queries, derivatives);
}

namespace {

/// The field file's bytes, checksum included (docs/field-format.md).
std::vector<unsigned char> fieldFileBytes(const Normalization& normalization, double f0,
                                          const Eigen::AlignedBox3d& bounds, const std::vector<double>& offsets,
                                          const std::vector<FieldLevel>& levels) {
  std::size_t size = sizeof kMagic + 4 + 4 + 8 * (3 + 1 + 1 + 6) + 4 + 8 * offsets.size() + 4 + 8;
  for (const FieldLevel& l : levels) size += 8 + 8 + 32 * static_cast<std::size_t>(l.centres.rows());
  Writer w(size);
  w.bytes(kMagic, sizeof kMagic);
  w.u32(kVersion);
  w.u32(0);  // flags, reserved
  for (int i = 0; i < 3; ++i) w.f64(normalization.centre[i]);
  w.f64(normalization.scale);
  w.f64(f0);
  for (int i = 0; i < 3; ++i) w.f64(bounds.min()[i]);
  for (int i = 0; i < 3; ++i) w.f64(bounds.max()[i]);
  w.u32(static_cast<std::uint32_t>(offsets.size()));
  for (double d : offsets) w.f64(d);
  w.u32(static_cast<std::uint32_t>(levels.size()));
  for (const FieldLevel& l : levels) {
    w.f64(l.sigma);
    w.u64(static_cast<std::uint64_t>(l.centres.rows()));
    for (Eigen::Index j = 0; j < l.centres.rows(); ++j) {
      w.f64(l.centres(j, 0));
      w.f64(l.centres(j, 1));
      w.f64(l.centres(j, 2));
      w.f64(l.weights[j]);
    }
  }
  return w.finish();
}

}  // namespace

void ImplicitField::save(std::ostream& out) const {
  const std::vector<unsigned char> bytes = fieldFileBytes(normalization_, f0_, bounds_, offsets_, levels_);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw IoError("cannot write the field file (stream error)");
}

void ImplicitField::save(const std::string& path) const {
  const std::vector<unsigned char> bytes = fieldFileBytes(normalization_, f0_, bounds_, offsets_, levels_);
  AtomicFile out(path);  // temporary file + rename: a failed save leaves nothing behind
  out.write(bytes.data(), bytes.size());
  out.commit();
}

ImplicitField ImplicitField::load(std::istream& in, const std::string& source) {
  Reader r(in, source);
  char magic[8];
  r.bytes(magic, 8, "the magic number");
  if (std::memcmp(magic, kMagic, 8) != 0) {
    throw IoError(source + ": not a duplexfit field file (bad magic number)");
  }
  const std::uint32_t version = r.u32("the version");
  if (version != kVersion) {
    throw IoError(source + ": field file version " + std::to_string(version) + " is not supported (this build reads version " +
                  std::to_string(kVersion) + ")");
  }
  (void)r.u32("the flags");
  Normalization n;
  for (int i = 0; i < 3; ++i) n.centre[i] = r.f64("the normalisation centre");
  n.scale = r.f64("the normalisation scale");
  if (!(n.scale > 0.0)) r.fail("the normalisation scale is not positive");
  const double f0 = r.f64("f0");
  Eigen::Vector3d lo, hi;
  for (int i = 0; i < 3; ++i) lo[i] = r.f64("the bounding box");
  for (int i = 0; i < 3; ++i) hi[i] = r.f64("the bounding box");
  const std::uint32_t nOffsets = r.u32("the offset count");
  if (nOffsets > 4096) r.fail("implausible offset count " + std::to_string(nOffsets));
  std::vector<double> offsets(nOffsets);
  for (double& d : offsets) d = r.f64("an offset");
  const std::uint32_t nLevels = r.u32("the level count");
  if (nLevels > 64) r.fail("implausible level count " + std::to_string(nLevels));
  std::vector<FieldLevel> levels(nLevels);
  for (std::uint32_t k = 0; k < nLevels; ++k) {
    FieldLevel& l = levels[k];
    l.sigma = r.f64("a level's sigma");
    if (!(l.sigma > 0.0)) r.fail("level " + std::to_string(k + 1) + " has a non-positive sigma");
    const std::uint64_t count = r.u64("a level's centre count");
    if (count > (std::uint64_t{1} << 31)) r.fail("implausible centre count at level " + std::to_string(k + 1));
    // Grow as we read so a corrupt count cannot allocate memory the file does not back.
    std::vector<double> data;
    for (std::uint64_t j = 0; j < count; ++j) {
      for (int c = 0; c < 4; ++c) data.push_back(r.f64("a centre"));
    }
    l.centres.resize(static_cast<Eigen::Index>(count), 3);
    l.weights.resize(static_cast<Eigen::Index>(count));
    for (std::uint64_t j = 0; j < count; ++j) {
      const auto i = static_cast<Eigen::Index>(j);
      l.centres.row(i) << data[4 * j], data[4 * j + 1], data[4 * j + 2];
      l.weights[i] = data[4 * j + 3];
    }
  }
  const std::uint64_t expected = r.hash();
  const std::uint64_t stored = r.u64("the checksum");
  if (stored != expected) throw IoError(source + ": field file checksum mismatch (the file is corrupt)");
  if (in.peek() != std::char_traits<char>::eof()) {
    throw IoError(source + ": unexpected data after the end of the field file");
  }
  // A valid checksum proves the bytes, not the numbers: a box of ±1e300 made `mesh` run 95 s and 1 GB.
  if (!n.centre.allFinite() || !std::isfinite(n.scale) || !std::isfinite(f0)) {
    throw IoError(source + ": the field's normalisation or f0 is not finite");
  }
  if (!lo.allFinite() || !hi.allFinite() || (hi - lo).minCoeff() < 0.0) {
    throw IoError(source + ": the field's bounding box is not finite or is inverted");
  }
  // A fit's box spans 1 in normalised units (its largest side, §1); allow generous slack, not 1e300.
  const double span = ((hi - lo) * n.scale).maxCoeff();
  const double reach = std::max((lo - n.centre).cwiseAbs().maxCoeff(), (hi - n.centre).cwiseAbs().maxCoeff()) * n.scale;
  if (!(span <= 1e3) || !(reach <= 1e3)) {
    std::ostringstream m;
    m << source << ": the field's bounding box spans " << span << " (reaching " << reach
      << " from its centre) in normalised units, where a fit's spans 1: the file is not a fit's";
    throw IoError(m.str());
  }
  for (double d : offsets) {
    if (!std::isfinite(d)) throw IoError(source + ": an offset of the field is not finite");
  }
  for (std::size_t k = 0; k < levels.size(); ++k) {
    if (!std::isfinite(levels[k].sigma) || !levels[k].centres.allFinite() || !levels[k].weights.allFinite()) {
      throw IoError(source + ": level " + std::to_string(k + 1) + " has a non-finite sigma, centre or weight");
    }
  }
  return ImplicitField(n, f0, std::move(levels), std::move(offsets), Eigen::AlignedBox3d(lo, hi));
}

ImplicitField ImplicitField::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path + ": cannot open the field file");
  return load(in, path);
}

}  // namespace duplexfit
