// Rings cut at +-180 read as written, uncut ones the short way (lon_unwrap.hpp), end to end:
// features written to a GeoPackage, read with read_sites, every cell of levels 6-8 labelled on
// the CPU and on CUDA, against a float64 reference of the exact rule written here:
//   - a cell whose centre GEOS puts inside a polygon (the polygon as it is meant, in flat lon/lat)
//     belongs to that polygon at distance 0;
//   - any other cell to the nearest site, by great-circle distance to the rings and lines drawn
//     straight in lon/lat (sampled twice as finely than the readers' pieces) and to the points.
// The readers cut edges into great-circle pieces a quarter cell long, which stray from the
// lon/lat curve by far less than the tolerance (a twentieth of a piece); a misread edge (a cap's
// parallel taken as a point, or a 90-degree chord that bulges 1.2 degrees) is off by degrees.
#include <gtest/gtest.h>

#include <ogr_api.h>
#include <ogr_geometry.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "label/label_math.hpp"
#include "label/labeller.hpp"
#include "sites/ogr_site_reader.hpp"
#include "sites/path_tracer.hpp"
#include "sites_test_support.hpp"

namespace qtmv::sites {
namespace {

using test::from_wkt;

/// One site: as written in the input, and what it means in flat lon/lat (cut at +-180, pole
/// lines explicit); empty `meaning`: as written.
struct SiteSpec {
  std::string written;
  std::string meaning;
};

struct CutCase {
  std::string name;
  std::vector<SiteSpec> sites;
  bool wrapped = false;        ///< -wrap auto joins some edge the short way: the reader warns
  bool geodesic_same = false;  ///< every ring edge runs along a meridian, parallel or pole line
};

/// Points around the globe that compete with the polygons for the other cells.
const std::vector<SiteSpec> kPoints = {{"POINT (45 60)", ""}, {"POINT (-120 35)", ""}, {"POINT (100 -50)", ""}};

std::vector<SiteSpec> with_points(std::vector<SiteSpec> sites) {
  sites.insert(sites.end(), kPoints.begin(), kPoints.end());
  return sites;
}

std::vector<CutCase> cases() {
  const std::string ne_antarctica_coast = "-180 -84,-150 -79,-120 -74,-60 -76,0 -70,60 -68,120 -66,150 -70,180 -84";
  const std::string ne_antarctica = "POLYGON((" + ne_antarctica_coast + ",180 -90,-180 -90,-180 -84))";
  const std::string cut_in_two = "MULTIPOLYGON(((170 -20,180 -20,180 -10,170 -10,170 -20)),"
                                 "((-180 -20,-170 -20,-170 -10,-180 -10,-180 -20)))";
  return {
      {"NorthCap", with_points({{"POLYGON((-180 86,180 86,180 90,-180 90,-180 86))", ""}}), false, true},
      {"NorthCapFromThePole", with_points({{"POLYGON((-180 86,-180 90,180 90,180 86,-180 86))", ""}}), false, true},
      {"NorthCapWithAHoleAndAnIsland",
       with_points({{"POLYGON((-180 84,-180 90,180 90,180 84,-180 84),(30 87,60 87,60 88.5,30 88.5,30 87))", ""},
                    {"POLYGON((40 87.5,50 87.5,50 88,40 88,40 87.5))", ""}})},
      {"SouthCap", with_points({{"POLYGON((-180 -80,180 -80,180 -90,-180 -90,-180 -80))", ""}}), false, true},
      {"SouthCapFromThePole", with_points({{"POLYGON((-180 -80,-180 -90,180 -90,180 -80,-180 -80))", ""}}), false,
       true},
      {"CapsWithPoleEdgesAt89_999",
       with_points({{"POLYGON((-180 86,180 86,180 89.999,-180 89.999,-180 86))", ""},
                    {"POLYGON((-180 -80,-180 -89.999,180 -89.999,180 -80,-180 -80))", ""}}),
       false, true},
      {"NaturalEarthAntarctica", with_points({{ne_antarctica, ""}})},
      {"NaturalEarthAntarcticaAt89_999",
       with_points({{"POLYGON((" + ne_antarctica_coast + ",180 -89.999,-180 -89.999,-180 -84))", ne_antarctica}})},
      {"WorldAtlasAntarcticaClosedByASeam",
       with_points({{"POLYGON((" + ne_antarctica_coast + ",-180 -84))", ne_antarctica}}), true},
      {"BandRoundTheGlobeAndAParallelLine",
       with_points({{"POLYGON((-180 -10,180 -10,180 10,-180 10,-180 -10))", ""},
                    {"LINESTRING(-180 70,180 70)", ""}}),
       false, true},
      {"PolygonCutInTwoAtTheAntimeridian", with_points({{cut_in_two, ""}})},
      {"UncutPolygonAcrossTheAntimeridian",
       with_points({{"POLYGON((170 -20,-170 -20,-170 -10,170 -10,170 -20))", cut_in_two}}), true},
      {"UncutSquareWithAVertexOnEachSideOfTheAntimeridian",
       with_points({{"POLYGON((170 -20,180 -20,-180 -20,-170 -20,-170 -10,-180 -10,180 -10,170 -10,170 -20))",
                     cut_in_two}}),
       true},
      {"UncutFijiLikeRingWithAJumpAndASeam",
       with_points({{"POLYGON((-180 -16,-175 -15,-180 -18,175 -19,176 -16,180 -16,-180 -16))",
                     "MULTIPOLYGON(((-180 -16,-175 -15,-180 -18,-180 -16)),((180 -18,175 -19,176 -16,180 -16,180 -18)))"}}),
       true},
  };
}

/// A site of the reference: polygons (GEOS, prepared) and the great-circle arcs between dense
/// samples of its rings and lines, in chunks with a bounding cap for pruning.
class ReferenceSite {
 public:
  ReferenceSite(const OGRGeometry& meaning, int level) : geometry_(meaning.clone()) {
    step_degrees_ = max_piece_degrees(level) / 2.0;
    add(*geometry_);
    if (has_area_) prepared_ = OGRCreatePreparedGeometry(OGRGeometry::ToHandle(geometry_.get()));
    for (std::size_t begin = 0; begin < arcs_.size(); begin += kFan) chunks_.push_back(bound(arcs_, begin));
    for (std::size_t begin = 0; begin < chunks_.size(); begin += kFan) groups_.push_back(bound(chunks_, begin));
  }
  ~ReferenceSite() {
    if (prepared_) OGRDestroyPreparedGeometry(prepared_);
  }
  ReferenceSite(const ReferenceSite&) = delete;
  ReferenceSite& operator=(const ReferenceSite&) = delete;
  bool contains(const grid::LonLat& p) const {
    if (!prepared_) return false;
    OGRPoint point(p.lon, p.lat);
    return OGRPreparedGeometryContains(prepared_, OGRGeometry::ToHandle(&point));
  }

  /// Great-circle distance (radians) from x to the site's rings, lines and points. The pruning
  /// works on chord lengths, a metric: |x - p| >= |x - centre| - radius.
  double distance(const grid::Vec3& x) const {
    double best = std::numeric_limits<double>::infinity();
    for (const Bound& g : groups_) best = std::min(best, chord(x, g.centre));  // a point of the curve
    for (const Bound& g : groups_) {
      if (chord(x, g.centre) - g.radius >= best) continue;
      for (std::size_t c = g.begin; c < g.end; ++c) {
        if (chord(x, chunks_[c].centre) - chunks_[c].radius >= best) continue;
        for (std::size_t k = chunks_[c].begin; k < chunks_[c].end; ++k) {
          best = std::min(best, std::sqrt(label::piece_chord2(x, arcs_[k])));
        }
      }
    }
    return label::chord2_to_angle(best * best);
  }

 private:
  static constexpr std::size_t kFan = 16;
  /// Items [begin, end) within the chord `radius` of `centre`, one of their points: a cap of
  /// less than a quarter circle holds the arcs between its points.
  struct Bound {
    std::size_t begin = 0, end = 0;
    grid::Vec3 centre{};
    double radius = 0;
  };
  static double chord(const grid::Vec3& a, const grid::Vec3& b) { return std::sqrt(grid::chord2(a, b)); }
  static grid::Vec3 any_point(const label::Piece& p) { return p.a; }
  static grid::Vec3 any_point(const Bound& b) { return b.centre; }
  static double reach(const grid::Vec3& centre, const label::Piece& p) {
    return std::max(chord(centre, p.a), chord(centre, p.b));
  }
  static double reach(const grid::Vec3& centre, const Bound& b) { return chord(centre, b.centre) + b.radius; }
  template <class Item>
  static Bound bound(const std::vector<Item>& items, std::size_t begin) {
    Bound b;
    b.begin = begin;
    b.end = std::min(items.size(), begin + kFan);
    b.centre = any_point(items[(b.begin + b.end) / 2]);
    for (std::size_t k = b.begin; k < b.end; ++k) b.radius = std::max(b.radius, reach(b.centre, items[k]));
    return b;
  }

  void add(const OGRGeometry& g) {
    switch (wkbFlatten(g.getGeometryType())) {
      case wkbPoint:
        arcs_.push_back(label::make_point_piece(grid::unit_vector(g.toPoint()->getX(), g.toPoint()->getY()), 0));
        break;
      case wkbLineString:
        add_curve(*g.toLineString());
        break;
      case wkbPolygon:
        has_area_ = true;
        for (const auto* ring : *g.toPolygon()) add_curve(*ring);
        break;
      default:
        for (const auto* part : *g.toGeometryCollection()) add(*part);
    }
  }

  /// Samples each edge straight in lon/lat, `step_degrees_` of arc apart at most.
  void add_curve(const OGRSimpleCurve& curve) {
    for (int k = 1; k < curve.getNumPoints(); ++k) {
      const double lon0 = curve.getX(k - 1), lat0 = curve.getY(k - 1), lon1 = curve.getX(k), lat1 = curve.getY(k);
      const bool crosses_equator = (lat0 <= 0) != (lat1 <= 0);
      const double cos_max = std::cos((crosses_equator ? 0.0 : std::min(std::fabs(lat0), std::fabs(lat1))) * M_PI / 180);
      const double length = std::hypot(lat1 - lat0, cos_max * (lon1 - lon0));
      const int steps = std::max(1, static_cast<int>(std::ceil(length / step_degrees_)));
      grid::Vec3 prev = grid::unit_vector(lon0, lat0);
      for (int s = 1; s <= steps; ++s) {
        const double t = static_cast<double>(s) / steps;
        const grid::Vec3 next = grid::unit_vector(lon0 + t * (lon1 - lon0), lat0 + t * (lat1 - lat0));
        arcs_.push_back(label::make_arc_piece(prev, next, 0));
        prev = next;
      }
    }
  }

  std::unique_ptr<OGRGeometry> geometry_;
  OGRPreparedGeometryH prepared_ = nullptr;
  bool has_area_ = false;
  double step_degrees_ = 0;
  std::vector<label::Piece> arcs_;
  std::vector<Bound> chunks_, groups_;
};

std::string dataset_of(const CutCase& c, const std::string& device) {
  std::vector<test::TestFeature> features;
  for (std::size_t s = 0; s < c.sites.size(); ++s) features.push_back({c.sites[s].written, "site" + std::to_string(s)});
  static int counter = 0;  // the parametrised tests' names hold a '/': not in the file name
  const std::string path =
      qtmv::test::process_temp_dir() + "/cut_rings_" + device + "_" + std::to_string(counter++) + "_" + c.name + ".gpkg";
  return test::make_dataset(path, "GPKG", "sites", "EPSG:4326", features);
}

class CutRings : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (GetParam() == "cuda" && label::cuda_device_count() == 0) GTEST_SKIP() << "no CUDA GPU";
  }

  /// Labels every cell of `level` from the case read with `edges`, and checks each against the
  /// reference. Returns the labels.
  label::LabelResult check(const CutCase& c, int level, EdgeShape edges) {
    const std::string what = c.name + " level " + std::to_string(level) +
                             (edges == EdgeShape::geodesic ? " geodesic" : "") + " on " + GetParam();
    std::vector<std::string> messages;
    ReadOptions read = test::options_at(level, &messages);
    read.edges = edges;
    read.warn_sites_without_cell = false;
    const SiteSet set = read_sites(dataset_of(c, GetParam()), read);
    EXPECT_EQ(test::any_contains(messages, "joined the short way across +-180"), c.wrapped) << what;
    label::LabelOptions options;
    options.device = GetParam();
    options.want_boundary = false;
    label::LabelResult result = label::label_all(set.geometry.input(), options);

    std::vector<std::unique_ptr<ReferenceSite>> reference;
    for (const SiteSpec& s : c.sites) {
      reference.push_back(std::make_unique<ReferenceSite>(*from_wkt(s.meaning.empty() ? s.written : s.meaning), level));
    }
    const double tolerance = 0.05 * max_piece_degrees(level) * M_PI / 180;  // radians
    const double tolerance_m = tolerance * label::kEarthRadiusMetres;
    const std::size_t sites = c.sites.size();
    const auto cells = static_cast<std::int64_t>(grid::cell_count(level));
    std::vector<double> distances(cells * sites);  // the reference's distances, on all cores
#pragma omp parallel for schedule(dynamic, 1024)
    for (std::int64_t code = 0; code < cells; ++code) {
      const grid::Vec3 x = grid::cell_centre_vector(static_cast<grid::Code>(code), level);
      for (std::size_t s = 0; s < sites; ++s) distances[code * sites + s] = reference[s]->distance(x);
    }
    std::size_t inside = 0, outside = 0, undecided = 0, failures = 0;
    for (std::int64_t code = 0; code < cells && failures < 10; ++code) {
      const grid::LonLat centre = grid::cell_centre(static_cast<grid::Code>(code), level);
      const double* d = &distances[code * sites];
      int owner = -1, nearest = 0, second = -1;
      for (std::size_t s = 0; s < sites; ++s) {
        if (owner < 0 && reference[s]->contains(centre)) owner = static_cast<int>(s);
        if (d[s] < d[nearest]) nearest = static_cast<int>(s);
      }
      for (std::size_t s = 0; s < sites; ++s) {
        if (static_cast<int>(s) != nearest && (second < 0 || d[s] < d[second])) second = static_cast<int>(s);
      }
      const std::int32_t got = result.site[code];
      const double got_m = result.distance_m[code];
      auto at = [&] {
        return what + ", cell " + std::to_string(code) + " at (" + std::to_string(centre.lon) + ", " +
               std::to_string(centre.lat) + ")";
      };
      if (owner >= 0 && d[owner] > tolerance) {  // inside, clear of the rings
        ++inside;
        if (got != owner || got_m != 0.0) {
          ++failures;
          ADD_FAILURE() << at() << ": inside site " << owner << ", got site " << got << " at " << got_m << " m";
        }
      } else if (owner < 0 && d[nearest] > tolerance) {  // outside every polygon
        ++outside;
        const bool tie = second >= 0 && d[second] - d[nearest] < 2 * tolerance;
        if (std::fabs(got_m - d[nearest] * label::kEarthRadiusMetres) > tolerance_m || (!tie && got != nearest)) {
          ++failures;
          ADD_FAILURE() << at() << ": nearest site " << nearest << " at " << d[nearest] * label::kEarthRadiusMetres
                        << " m, got site " << got << " at " << got_m << " m";
        }
      } else {
        ++undecided;  // a centre on a ring, within the pieces' tolerance
      }
    }
    EXPECT_GT(inside, 0u) << what;
    EXPECT_GT(outside, grid::cell_count(level) / 4) << what;
    EXPECT_LT(undecided, grid::cell_count(level) / 50) << what;
    return result;
  }
};

TEST_P(CutRings, EveryCellMatchesTheReferenceAtLevels6To8) {
  for (const CutCase& c : cases()) {
    for (int level : {6, 7, 8}) {
      check(c, level, EdgeShape::lonlat);
      if (c.geodesic_same && level < 8) check(c, level, EdgeShape::geodesic);
    }
  }
}

TEST_P(CutRings, CellsJustOutsideACapKeepTheirDistanceToItsParallel) {
  // The case: at 88N the cell is inside the cap; at 85.5N it is half a degree from the
  // parallel 86N (55.6 km), not 4 or 5 degrees from a line along +-180.
  const CutCase c = cases()[0];
  const int level = 8;
  const label::LabelResult r = check(c, level, EdgeShape::lonlat);
  const grid::Code inside = grid::lonlat_to_code(45, 88, level);
  EXPECT_EQ(r.site[inside], 0);
  EXPECT_EQ(r.distance_m[inside], 0.0f);
  for (double lon : {-179.9, -90.0, 0.0, 45.0, 135.0, 179.9}) {
    const grid::Code code = grid::lonlat_to_code(lon, 85.5, level);
    const double lat = grid::cell_centre(code, level).lat;
    const double expected_m = (86.0 - lat) * M_PI / 180 * label::kEarthRadiusMetres;
    EXPECT_EQ(r.site[code], 0) << lon;
    EXPECT_NEAR(r.distance_m[code], expected_m, 0.002 * expected_m) << lon;
  }
}

INSTANTIATE_TEST_SUITE_P(Cpu, CutRings, ::testing::Values(std::string("cpu")));
INSTANTIATE_TEST_SUITE_P(Cuda, CutRings, ::testing::Values(std::string("cuda")));

}  // namespace
}  // namespace qtmv::sites
