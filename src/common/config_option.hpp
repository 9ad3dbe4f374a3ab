// The one way every part reads a run switch that is not a command-line option: the trace channel
// (QTMV_TRACE, trace.hpp) and the tests' fault injection (QTMV_FAULT_*). A GDAL-aware program
// installs GDAL's configuration options as the lookup (they fall back to the environment), so
// `--config QTMV_TRACE write` works as `--config CPL_DEBUG ON` does; without one, the environment.
#pragma once

#include <string>

namespace qtmv {

/// How a switch is looked up: GDAL's CPLGetConfigOption has this shape.
using ConfigLookup = const char* (*)(const char* name, const char* default_value);

/// Makes `lookup` the process's lookup (nullptr: the environment again). Process-wide, as GDAL's
/// configuration is.
void set_config_lookup(ConfigLookup lookup);

/// The value of switch `name`, or nullptr when it is not set.
const char* config_option(const char* name);

/// True when switch `name` is set to a true value (YES, ON, TRUE, 1, or any other value but
/// NO, OFF, FALSE, 0 and the empty string), as GDAL's CPLTestBool reads one.
bool config_flag(const char* name);

/// The fault a test asks `name` (QTMV_FAULT_*) to inject: its value, or "" when none.
std::string fault_switch(const char* name);

}  // namespace qtmv
