#include "sites/site_table.hpp"

#include <utility>

namespace qtmv::sites {

SiteTable::SiteTable(SiteTable&& other) noexcept
    : sites(std::move(other.sites)), sources_(std::exchange(other.sources_, {})) {}

SiteTable& SiteTable::operator=(SiteTable&& other) noexcept {
  if (this != &other) {
    sites = std::move(other.sites);
    release_sources();
    sources_ = std::exchange(other.sources_, {});
  }
  return *this;
}

SiteTable::~SiteTable() {
  sites.clear();  // the features first: they hold references to the definitions too
  release_sources();
}

void SiteTable::release_sources() {
  for (Source& source : sources_) {
    if (source.definition) source.definition->Release();
  }
  sources_.clear();
}

void SiteTable::set_source(OGRFeatureDefn* definition, std::string dataset, std::string layer) {
  if (definition) definition->Reference();  // before the release: it may be the same definition
  release_sources();
  sources_.push_back({definition, std::move(dataset), std::move(layer)});
}

std::uint32_t SiteTable::add_source(OGRFeatureDefn* definition, std::string dataset, std::string layer) {
  if (definition) definition->Reference();
  sources_.push_back({definition, std::move(dataset), std::move(layer)});
  return static_cast<std::uint32_t>(sources_.size() - 1);
}

}  // namespace qtmv::sites
