// Consumer check: links the installed duplexfit, assembles a small Wendland system and solves it on
// the reference device and on the default device. Exit status 0 only if both converge and agree.
#include <duplexfit/device.hpp>
#include <duplexfit/linalg.hpp>
#include <duplexfit/wendland.hpp>

#include <cmath>
#include <iostream>

int main() {
  using namespace duplexfit;
  const int n = 400;
  Points centres(n, 3);
  for (int i = 0; i < n; ++i) {  // a Fibonacci sphere of radius 0.5
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double r = std::sqrt(1.0 - z * z);
    const double phi = 2.399963229728653 * i;
    centres.row(i) << 0.5 * r * std::cos(phi), 0.5 * r * std::sin(phi), 0.5 * z;
  }
  const CsrMatrix a = assembleWendland(centres, 0.2);
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(n);
  Eigen::VectorXd solutions[2];
  const Device devices[2] = {Device::reference(), Device::openDefault()};
  for (int k = 0; k < 2; ++k) {
    const DeviceCsr m = DeviceCsr::upload(devices[k], a, Precision::Float);
    const DeviceVector db = DeviceVector::upload(devices[k], b, Precision::Float);
    DeviceVector x(devices[k], n, Precision::Float);
    const SolveStats s = solveCg(m, db, x);
    std::cout << devices[k].description() << ": " << s.iterations << " iterations, residual "
              << s.relativeResidual << " (" << stopReasonName(s.reason) << ")\n";
    if (!s.converged) return 1;
    solutions[k] = x.download();
  }
  const double diff = (solutions[0] - solutions[1]).norm() / solutions[0].norm();
  std::cout << "relative difference " << diff << "\n";
  return diff < 1e-3 ? 0 : 1;
}
