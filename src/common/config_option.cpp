#include "common/config_option.hpp"

#include <atomic>
#include <cctype>
#include <cstdlib>

namespace qtmv {

namespace {

std::atomic<ConfigLookup> g_lookup{nullptr};

bool equals_ignoring_case(const char* a, const char* b) {
  for (; *a && *b; ++a, ++b) {
    if (std::tolower(static_cast<unsigned char>(*a)) != std::tolower(static_cast<unsigned char>(*b))) return false;
  }
  return *a == *b;
}

}  // namespace

void set_config_lookup(ConfigLookup lookup) { g_lookup.store(lookup); }

const char* config_option(const char* name) {
  if (const ConfigLookup lookup = g_lookup.load()) return lookup(name, nullptr);
  return std::getenv(name);
}

bool config_flag(const char* name) {
  const char* value = config_option(name);
  if (!value || !*value) return false;
  for (const char* no : {"NO", "OFF", "FALSE", "0"}) {
    if (equals_ignoring_case(value, no)) return false;
  }
  return true;
}

std::string fault_switch(const char* name) {
  const char* value = config_option(name);
  return value ? value : "";
}

}  // namespace qtmv
