// `duplexfit devices`: every compute device (spec, platform, name, type, memory, fp64, driver), as a table
// or as JSON.
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "commands.hpp"
#include "options.hpp"
#include "duplexfit/device.hpp"

namespace duplexfit::cli {

namespace {

std::string mib(std::uint64_t bytes) {
  std::ostringstream s;
  s << (bytes >> 20) << " MiB";
  return s.str();
}

}  // namespace

int cmdDevices(int argc, char** argv) {
  CLI::App app("list every compute device", "devices");
  bool json = false, quiet = false;
  addJson(app, json);
  addQuiet(app, quiet);
  if (parse(app, argc, argv)) return 0;
  std::vector<DeviceInfo> all = Device::enumerate();
  all.push_back(Device::reference().info());
  const std::string defaultSpec = Device::openDefault().info().spec;
  if (json) {
    nlohmann::ordered_json list = nlohmann::ordered_json::array();
    for (const DeviceInfo& d : all) {
      list.push_back({{"spec", d.spec},
                      {"platform", d.platform},
                      {"name", d.name},
                      {"vendor", d.vendor},
                      {"type", deviceTypeName(d.type)},
                      {"compute_units", d.computeUnits},
                      {"global_mem_bytes", d.globalMemBytes},
                      {"max_alloc_bytes", d.maxAllocBytes},
                      {"fp64", d.fp64},
                      {"opencl_c_version", d.openclCVersion},
                      {"device_version", d.deviceVersion},
                      {"driver_version", d.driverVersion}});
    }
    const nlohmann::ordered_json out{{"default", defaultSpec}, {"devices", std::move(list)}};
    std::cout << out.dump(2, ' ', false, nlohmann::ordered_json::error_handler_t::replace) << "\n";
    return 0;
  }
  std::cout << std::left << std::setw(6) << "spec" << std::setw(30) << "platform" << std::setw(40) << "name"
            << std::setw(6) << "type" << std::right << std::setw(5) << "CUs" << std::setw(12) << "global"
            << std::setw(12) << "max alloc" << std::setw(6) << "fp64" << "  " << std::left << std::setw(20)
            << "OpenCL C" << "driver\n";
  for (const DeviceInfo& d : all) {
    std::cout << std::left << std::setw(6) << (d.spec == defaultSpec ? d.spec + "*" : d.spec) << std::setw(30)
              << d.platform.substr(0, 29) << std::setw(40) << d.name.substr(0, 39) << std::setw(6)
              << deviceTypeName(d.type) << std::right << std::setw(5) << d.computeUnits << std::setw(12)
              << mib(d.globalMemBytes) << std::setw(12) << mib(d.maxAllocBytes) << std::setw(6)
              << (d.fp64 ? "yes" : "no") << "  " << std::left << std::setw(20) << d.openclCVersion
              << d.driverVersion << "\n";
  }
  std::cout << "(* = default device; choose with --device SPEC or DUPLEXFIT_DEVICE)\n";
  return 0;
}

}  // namespace duplexfit::cli
