// The readers' output types: the labeller's plain input structs (SitePiece, SiteCell, FixedCell,
// FixedNode, SiteGeometry), taken from its input port so that what the readers produce is what it reads.
#pragma once

#include "label/label_input.hpp"

namespace qtmv::sites {

using label::FixedCell;
using label::FixedNode;
using label::SiteCell;
using label::SiteGeometry;
using label::SitePiece;
using grid::Vec3;

}  // namespace qtmv::sites
