// duplexfit-field-bench FIELD.dpxf MESH [--device SPEC] [--repeat N] [--points N]: the cost of evaluating a
// fitted field (f alone, then f and ∇f) at the vertices of a mesh of it (the near-surface points that mesh
// sampling, projection and the deviation measure evaluate), on one device; prints the minimum of N runs in
// microseconds per point and the field's centres per level. docs/benchmarks.md ("Field evaluation") keeps
// the figures.
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <string>

#include "duplexfit/device.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/io.hpp"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << "usage: duplexfit-field-bench FIELD.dpxf MESH [--device SPEC] [--repeat N] [--points N]\n";
    return 1;
  }
  try {
    std::string spec;
    int repeat = 3;
    long points = 0;
    for (int i = 3; i + 1 < argc; i += 2) {
      const std::string a = argv[i];
      if (a == "--device") spec = argv[i + 1];
      else if (a == "--repeat") repeat = std::max(1, std::atoi(argv[i + 1]));
      else if (a == "--points") points = std::atol(argv[i + 1]);
      else throw std::runtime_error("unknown option " + a);
    }
    const duplexfit::ImplicitField field = duplexfit::ImplicitField::load(argv[1]);
    const duplexfit::Mesh mesh = duplexfit::readMesh(argv[2]);
    duplexfit::Points q = mesh.vertices;
    if (points > 0 && points < q.rows()) q.conservativeResize(points, 3);
    const duplexfit::Device device = spec.empty() ? duplexfit::Device::openDefault() : duplexfit::Device::open(spec);
    device.compileKernels(duplexfit::Precision::Float);
    const auto t0 = std::chrono::steady_clock::now();
    const duplexfit::FieldEvaluator evaluator(device, field);
    const double setup = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cout << "device " << device.description() << ", " << field.levels().size() << " levels, " << q.rows()
              << " points, evaluator set-up " << setup << " s\n";
    for (const auto d : {duplexfit::FieldDerivatives::None, duplexfit::FieldDerivatives::Gradient}) {
      double best = std::numeric_limits<double>::infinity();
      double checksum = 0.0;
      for (int r = 0; r < repeat; ++r) {
        const auto t = std::chrono::steady_clock::now();
        const duplexfit::FieldSamples s = evaluator.evaluate(q, d);
        best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count());
        checksum = s.values.cwiseAbs().sum();
      }
      std::cout << (d == duplexfit::FieldDerivatives::None ? "value    " : "gradient ") << 1e6 * best / static_cast<double>(q.rows())
                << " us/point (" << best << " s), sum |f| " << checksum << "\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "duplexfit-field-bench: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
