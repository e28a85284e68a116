// A few host threads that take items until none is left (private to the library): the meshes finished at
// once (finishSurfaces) and the pipelines' per-mesh tasks.
#pragma once

#include <algorithm>
#include <cstddef>
#include <system_error>
#include <thread>
#include <vector>

namespace duplexfit::detail {

/// Workers for n items when `asked` were asked for (0: as many as the host has hardware threads, at most 4).
inline std::size_t workersFor(std::size_t asked, std::size_t n) {
  const std::size_t w = asked > 0 ? asked : std::clamp<std::size_t>(std::thread::hardware_concurrency(), 1, 4);
  return std::min(w, n);
}

/// Runs work(false) on workers − 1 new threads and work(true) on this one, then joins them. `work` takes
/// items until none is left, so when no thread can be started the calling thread's call does it all.
template <typename Work>
void runOnWorkers(std::size_t workers, const Work& work) {
  std::vector<std::thread> helpers;
  try {
    for (std::size_t w = 1; w < workers; ++w) helpers.emplace_back(work, false);
  } catch (const std::system_error&) {
    // no thread to spare: the remaining items are taken here
  }
  work(true);
  for (std::thread& h : helpers) h.join();
}

}  // namespace duplexfit::detail
