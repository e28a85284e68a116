// The CLI's stopwatch is the library's (duplexfit/timer.hpp).
#pragma once

#include "duplexfit/timer.hpp"

namespace duplexfit::cli {

using duplexfit::Timer;

}  // namespace duplexfit::cli
