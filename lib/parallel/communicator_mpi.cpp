// The MPI communicator: MPI_COMM_WORLD. Compiled only in MPI builds; the only file that includes mpi.h.
#include <mpi.h>

#include <climits>
#include <cstdlib>
#include <mutex>

#include "duplexfit/communicator.hpp"
#include "duplexfit/error.hpp"

namespace duplexfit {

namespace {

int checkedInt(std::size_t n, const char* what) {
  if (n > static_cast<std::size_t>(INT_MAX)) {
    throw InvalidArgument(std::string("MPI ") + what + ": " + std::to_string(n) +
                          " bytes exceed the 2^31 - 1 of one MPI message");
  }
  return static_cast<int>(n);
}

void check(int rc, const char* what) {
  if (rc != MPI_SUCCESS) {
    char text[MPI_MAX_ERROR_STRING];
    int len = 0;
    MPI_Error_string(rc, text, &len);
    throw Error(std::string("MPI ") + what + " failed: " + std::string(text, static_cast<std::size_t>(len)));
  }
}

MPI_Op opOf(ReduceOp op) { return op == ReduceOp::Sum ? MPI_SUM : op == ReduceOp::Min ? MPI_MIN : MPI_MAX; }

void finalize() {
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (finalized == 0) MPI_Finalize();
}

class MpiCommunicator final : public Communicator {
 public:
  MpiCommunicator() {
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  }
  int rank() const noexcept override { return rank_; }
  int size() const noexcept override { return size_; }
  std::string name() const override {
    char version[MPI_MAX_LIBRARY_VERSION_STRING];
    int len = 0;
    MPI_Get_library_version(version, &len);
    std::string v(version, static_cast<std::size_t>(len));
    const auto cut = v.find_first_of(",\n");
    return "MPI (" + (cut == std::string::npos ? v : v.substr(0, cut)) + ")";
  }
  void barrier() override { check(MPI_Barrier(MPI_COMM_WORLD), "barrier"); }
  void allreduce(double* values, std::size_t n, ReduceOp op) override {
    check(MPI_Allreduce(MPI_IN_PLACE, values, checkedInt(n, "allreduce"), MPI_DOUBLE, opOf(op), MPI_COMM_WORLD),
          "allreduce");
  }
  void allreduce(std::int64_t* values, std::size_t n, ReduceOp op) override {
    check(MPI_Allreduce(MPI_IN_PLACE, values, checkedInt(n, "allreduce"), MPI_INT64_T, opOf(op), MPI_COMM_WORLD),
          "allreduce");
  }
  std::vector<unsigned char> allgatherv(const void* data, std::size_t bytes, std::vector<std::size_t>* counts) override {
    int mine = checkedInt(bytes, "allgatherv");
    std::vector<int> sizes(static_cast<std::size_t>(size_)), displs(static_cast<std::size_t>(size_));
    check(MPI_Allgather(&mine, 1, MPI_INT, sizes.data(), 1, MPI_INT, MPI_COMM_WORLD), "allgather");
    std::size_t total = 0;
    for (int r = 0; r < size_; ++r) {
      displs[static_cast<std::size_t>(r)] = checkedInt(total, "allgatherv");
      total += static_cast<std::size_t>(sizes[static_cast<std::size_t>(r)]);
    }
    checkedInt(total, "allgatherv");
    std::vector<unsigned char> out(total);
    check(MPI_Allgatherv(data, mine, MPI_BYTE, out.data(), sizes.data(), displs.data(), MPI_BYTE, MPI_COMM_WORLD),
          "allgatherv");
    if (counts != nullptr) {
      counts->clear();
      for (const int s : sizes) counts->push_back(static_cast<std::size_t>(s));
    }
    return out;
  }
  std::vector<unsigned char> alltoallv(const std::vector<std::vector<unsigned char>>& send,
                                       std::vector<std::size_t>& counts) override {
    if (send.size() != static_cast<std::size_t>(size_)) {
      throw InvalidArgument("alltoallv: " + std::to_string(send.size()) + " send buffers for " +
                            std::to_string(size_) + " ranks");
    }
    const auto p = static_cast<std::size_t>(size_);
    std::vector<int> sendCounts(p), sendDispls(p), recvCounts(p), recvDispls(p);
    std::vector<unsigned char> packed;
    for (std::size_t r = 0; r < p; ++r) {
      sendCounts[r] = checkedInt(send[r].size(), "alltoallv");
      sendDispls[r] = checkedInt(packed.size(), "alltoallv");
      packed.insert(packed.end(), send[r].begin(), send[r].end());
    }
    check(MPI_Alltoall(sendCounts.data(), 1, MPI_INT, recvCounts.data(), 1, MPI_INT, MPI_COMM_WORLD), "alltoall");
    std::size_t total = 0;
    counts.assign(p, 0);
    for (std::size_t r = 0; r < p; ++r) {
      recvDispls[r] = checkedInt(total, "alltoallv");
      counts[r] = static_cast<std::size_t>(recvCounts[r]);
      total += counts[r];
    }
    checkedInt(total, "alltoallv");
    std::vector<unsigned char> out(total);
    check(MPI_Alltoallv(packed.data(), sendCounts.data(), sendDispls.data(), MPI_BYTE, out.data(), recvCounts.data(),
                        recvDispls.data(), MPI_BYTE, MPI_COMM_WORLD),
          "alltoallv");
    return out;
  }
  void broadcast(void* data, std::size_t bytes, int root) override {
    check(MPI_Bcast(data, checkedInt(bytes, "broadcast"), MPI_BYTE, root, MPI_COMM_WORLD), "broadcast");
  }
  [[noreturn]] void abort(int code) override {
    MPI_Abort(MPI_COMM_WORLD, code);
    std::exit(code);
  }

 private:
  int rank_ = 0, size_ = 1;
};

}  // namespace

bool mpiBuilt() noexcept { return true; }

std::shared_ptr<Communicator> mpiWorldCommunicator() {
  static std::once_flag once;
  static std::shared_ptr<Communicator> world;
  std::call_once(once, [] {
    int initialized = 0;
    MPI_Initialized(&initialized);
    if (initialized == 0) {
      int provided = 0;
      check(MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided), "init");
      std::atexit(finalize);
    }
    world = std::make_shared<MpiCommunicator>();
  });
  return world;
}

}  // namespace duplexfit
