#include "sites/site_table.hpp"

#include <utility>

namespace qtmv::sites {

SiteTable::SiteTable(SiteTable&& other) noexcept
    : sites(std::move(other.sites)),
      definition_(std::exchange(other.definition_, nullptr)),
      dataset_(std::move(other.dataset_)),
      layer_(std::move(other.layer_)) {}

SiteTable& SiteTable::operator=(SiteTable&& other) noexcept {
  if (this != &other) {
    sites = std::move(other.sites);
    if (definition_) definition_->Release();
    definition_ = std::exchange(other.definition_, nullptr);
    dataset_ = std::move(other.dataset_);
    layer_ = std::move(other.layer_);
  }
  return *this;
}

SiteTable::~SiteTable() {
  sites.clear();  // the features first: they hold references to the definition too
  if (definition_) definition_->Release();
}

void SiteTable::set_source(OGRFeatureDefn* definition, std::string dataset, std::string layer) {
  if (definition) definition->Reference();
  if (definition_) definition_->Release();
  definition_ = definition;
  dataset_ = std::move(dataset);
  layer_ = std::move(layer);
}

}  // namespace qtmv::sites
