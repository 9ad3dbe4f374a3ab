// The QTM grid: codes, geometry and topology, for host and device code alike.
#pragma once

#include "qtm_code.hpp"
#include "qtm_geometry.hpp"
#include "qtm_hierarchy.hpp"
#include "qtm_math.hpp"
#include "qtm_topology.hpp"
