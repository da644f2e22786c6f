// Errors at the edges of the program. Each maps to one exit code of the command line:
//   InputError  -> 2 (bad file, field, option or limit; the message names it)
//   DeviceError -> 3 (no usable Vulkan device or a missing device feature)
// Anything else escaping to main is an internal error (exit 1).
#pragma once

#include <stdexcept>
#include <string>

namespace hp {

struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct DeviceError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace hp
