// A small message-passing interface for the distributed fit (docs/method.md, "Distributed fit"): the
// collectives it needs and nothing else. The serial implementation is always built; the MPI one only when
// the build found MPI (DUPLEXFIT_WITH_MPI), and MPI's headers stay inside lib/parallel/communicator_mpi.cpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

namespace duplexfit {

enum class ReduceOp { Sum, Min, Max };

/// A group of ranks 0 … size − 1 that take part in every collective call in the same order.
class Communicator {
 public:
  virtual ~Communicator() = default;
  virtual int rank() const noexcept = 0;
  virtual int size() const noexcept = 0;
  /// "serial" or "MPI (Open MPI ...)".
  virtual std::string name() const = 0;
  virtual void barrier() = 0;
  /// Element-wise reduction of `values[0 … n)` over the ranks, the result on every rank.
  virtual void allreduce(double* values, std::size_t n, ReduceOp op) = 0;
  virtual void allreduce(std::int64_t* values, std::size_t n, ReduceOp op) = 0;
  /// Every rank's bytes concatenated in rank order, on every rank; `counts` (if not null) gets each
  /// rank's byte count.
  virtual std::vector<unsigned char> allgatherv(const void* data, std::size_t bytes,
                                                std::vector<std::size_t>* counts = nullptr) = 0;
  /// send[r] goes to rank r; returns what every rank sent to this one, concatenated in rank order, with
  /// each source's byte count in `counts`.
  virtual std::vector<unsigned char> alltoallv(const std::vector<std::vector<unsigned char>>& send,
                                               std::vector<std::size_t>& counts) = 0;
  /// `bytes` bytes at `data` from `root` to every rank.
  virtual void broadcast(void* data, std::size_t bytes, int root) = 0;
  /// Ends every rank of the group with exit status `code` (MPI_Abort); the serial one calls std::exit.
  [[noreturn]] virtual void abort(int code) = 0;

  // Typed conveniences.
  double allreduce(double v, ReduceOp op) { allreduce(&v, 1, op); return v; }
  std::int64_t allreduce(std::int64_t v, ReduceOp op) { allreduce(&v, 1, op); return v; }
  /// Trivially copyable elements of every rank, concatenated in rank order; `counts` in elements.
  template <class T>
  std::vector<T> allgather(const std::vector<T>& mine, std::vector<std::size_t>* counts = nullptr) {
    static_assert(std::is_trivially_copyable_v<T>);
    std::vector<std::size_t> bytes;
    const std::vector<unsigned char> all = allgatherv(mine.data(), mine.size() * sizeof(T), &bytes);
    std::vector<T> out(all.size() / sizeof(T));
    if (!all.empty()) std::memcpy(out.data(), all.data(), all.size());
    if (counts != nullptr) {
      counts->clear();
      for (const std::size_t b : bytes) counts->push_back(b / sizeof(T));
    }
    return out;
  }
};

/// One rank, size 1: every collective is a copy.
std::unique_ptr<Communicator> makeSerialCommunicator();

/// Whether this build has the MPI implementation (CMake DUPLEXFIT_WITH_MPI with MPI found).
bool mpiBuilt() noexcept;

/// Whether the process looks launched by mpirun/mpiexec/srun with more than one rank (environment:
/// OMPI_COMM_WORLD_SIZE, PMI_SIZE, PMIX_SIZE... ), without initialising MPI.
bool launchedWithSeveralRanks() noexcept;

/// MPI_COMM_WORLD (MPI_Init on the first call, MPI_Finalize at exit). @throws InvalidArgument when the
/// build has no MPI.
std::shared_ptr<Communicator> mpiWorldCommunicator();

}  // namespace duplexfit
