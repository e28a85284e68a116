// The serial communicator (always built) and the environment test for mpirun.
#include <cstdlib>
#include <cstring>

#include "duplexfit/communicator.hpp"
#include "duplexfit/error.hpp"

namespace duplexfit {

namespace {

class SerialCommunicator final : public Communicator {
 public:
  int rank() const noexcept override { return 0; }
  int size() const noexcept override { return 1; }
  std::string name() const override { return "serial"; }
  void barrier() override {}
  void allreduce(double*, std::size_t, ReduceOp) override {}
  void allreduce(std::int64_t*, std::size_t, ReduceOp) override {}
  std::vector<unsigned char> allgatherv(const void* data, std::size_t bytes, std::vector<std::size_t>* counts) override {
    if (counts != nullptr) *counts = {bytes};
    const auto* p = static_cast<const unsigned char*>(data);
    return bytes == 0 ? std::vector<unsigned char>{} : std::vector<unsigned char>(p, p + bytes);
  }
  std::vector<unsigned char> alltoallv(const std::vector<std::vector<unsigned char>>& send,
                                       std::vector<std::size_t>& counts) override {
    if (send.size() != 1) throw InvalidArgument("alltoallv: expected 1 send buffer, got " + std::to_string(send.size()));
    counts = {send[0].size()};
    return send[0];
  }
  void broadcast(void*, std::size_t, int root) override {
    if (root != 0) throw InvalidArgument("broadcast: root " + std::to_string(root) + " of a serial communicator");
  }
  [[noreturn]] void abort(int code) override { std::exit(code); }
};

bool severalIn(const char* variable) {
  const char* v = std::getenv(variable);
  return v != nullptr && std::atoi(v) > 1;
}

}  // namespace

std::unique_ptr<Communicator> makeSerialCommunicator() { return std::make_unique<SerialCommunicator>(); }

bool launchedWithSeveralRanks() noexcept {
  return severalIn("OMPI_COMM_WORLD_SIZE") || severalIn("PMI_SIZE") || severalIn("PMIX_SIZE") ||
         severalIn("MPI_LOCALNRANKS") || severalIn("SLURM_NTASKS");
}

#ifndef DUPLEXFIT_HAVE_MPI
bool mpiBuilt() noexcept { return false; }
std::shared_ptr<Communicator> mpiWorldCommunicator() {
  throw InvalidArgument("this duplexfit was built without MPI (install libopenmpi-dev and rebuild with "
                        "-DDUPLEXFIT_WITH_MPI=ON)");
}
#endif

}  // namespace duplexfit
