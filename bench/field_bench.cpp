// duplexfit-field-bench FIELD.dpxf MESH [--device SPEC] [--repeat N] [--points N]: the cost of evaluating a
// fitted field (f alone, then f and ∇f) at the vertices of a mesh of it (the near-surface points that mesh
// sampling, projection and the deviation measure evaluate), on one device; prints the minimum of N runs in
// microseconds per point. --check compares every result with the reference device in double precision
// (the largest |f − f_ref| as a fraction of the field's box side, and of |∇f − ∇f_ref|).
// DUPLEXFIT_FIELD_KERNEL=scalar|vector picks a CPU device's kernel. docs/benchmarks.md ("Projection cost",
// "Field evaluation per point") keeps the figures.
#include <algorithm>
#include <iostream>
#include <limits>
#include <string>

#include <CLI/CLI.hpp>

#include "duplexfit/device.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/timer.hpp"

int main(int argc, char** argv) {
  CLI::App app{"duplexfit-field-bench: microseconds per point for f and grad f at a mesh's vertices"};
  std::string fieldPath, meshPath, spec;
  int repeat = 3;
  long long points = 0;
  bool check = false;
  app.add_option("FIELD", fieldPath, "a saved field (.dpxf)")->required();
  app.add_option("MESH", meshPath, "a mesh whose vertices are the query points")->required();
  app.add_option("--device", spec, "device spec (default: the default device)");
  app.add_option("--repeat", repeat, "runs of each evaluation; the minimum is printed")->check(CLI::PositiveNumber);
  app.add_option("--points", points, "use the first N vertices (0: all)")->check(CLI::NonNegativeNumber);
  app.add_flag("--check", check, "compare with the reference device in double precision");
  CLI11_PARSE(app, argc, argv);
  try {
    const duplexfit::ImplicitField field = duplexfit::ImplicitField::load(fieldPath);
    const duplexfit::Mesh mesh = duplexfit::readMesh(meshPath);
    duplexfit::Points q = mesh.vertices;
    if (points > 0 && points < q.rows()) q.conservativeResize(static_cast<Eigen::Index>(points), 3);
    const duplexfit::Device device = spec.empty() ? duplexfit::Device::openDefault() : duplexfit::Device::open(spec);
    device.compileKernels(duplexfit::Precision::Float);
    const duplexfit::Timer setup;
    const duplexfit::FieldEvaluator evaluator(device, field);
    std::cout << "device " << device.description() << " [" << device.tuning().describe() << "], "
              << field.levels().size() << " levels, " << q.rows() << " points, evaluator set-up " << setup.seconds()
              << " s\n";
    duplexfit::FieldSamples exact;
    if (check) {
      const duplexfit::FieldEvaluator reference(duplexfit::Device::reference(), field, duplexfit::Precision::Double);
      exact = reference.evaluate(q, duplexfit::FieldDerivatives::Gradient);
    }
    const double side = field.bounds().sizes().maxCoeff();
    for (const auto d : {duplexfit::FieldDerivatives::None, duplexfit::FieldDerivatives::Gradient}) {
      double best = std::numeric_limits<double>::infinity();
      double checksum = 0.0;
      duplexfit::FieldSamples s;
      for (int r = 0; r < repeat; ++r) {
        const duplexfit::Timer t;
        s = evaluator.evaluate(q, d);
        best = std::min(best, t.seconds());
        checksum = s.values.cwiseAbs().sum();
      }
      std::cout << (d == duplexfit::FieldDerivatives::None ? "value    " : "gradient ") << 1e6 * best / static_cast<double>(q.rows())
                << " us/point (" << best << " s), sum |f| " << checksum;
      if (check) {
        std::cout << ", max |f - f_ref| / side " << (s.values - exact.values).cwiseAbs().maxCoeff() / side;
        if (d == duplexfit::FieldDerivatives::Gradient) {
          std::cout << ", max |grad f - grad f_ref| " << (s.gradients - exact.gradients).rowwise().norm().maxCoeff();
        }
      }
      std::cout << "\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "duplexfit-field-bench: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
