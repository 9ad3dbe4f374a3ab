// A raster's strips filled with values (see raster_strips.hpp).
#include "write/raster_strips.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>

#include "common/host_info.hpp"
#include "grid/qtm.hpp"
#include "write/raster_bands.hpp"
#include "write/raster_types.hpp"

namespace qtmv::write {

namespace {

using grid::Code;

/// A pixel without a cell (the QTM-coded raster's columns past a row's end, lon/lat centres past
/// latitude -90): nodata in every band.
constexpr std::uint64_t kNoCell = ~std::uint64_t{0};

/// Where the strip's labels lie: runs of consecutive codes (the QTM-coded raster's strip, or a
/// lon/lat strip's rows of cells in each octant), or the pixels' own (a lon/lat strip labelled
/// point by point: entry r * width + x for pixel x of the strip's row r).
struct LabelSpans {
  struct Span {
    Code first = 0;
    std::uint64_t count = 0;
    std::uint64_t offset = 0;  ///< index of its first code's labels
  };
  Span by_octant[grid::kOctants];  ///< runs; count 0: none in that octant
  bool by_pixel = false;
  std::uint64_t pixels = 0;  ///< labels by pixel: how many

  std::uint64_t size() const {
    if (by_pixel) return pixels;
    std::uint64_t n = 0;
    for (const Span& s : by_octant) n += s.count;
    return n;
  }
};

/// Consecutive pixel columns [begin, end) whose centres' longitudes lie in one quadrant.
struct QuadrantRun {
  std::size_t begin = 0, end = 0;
  int quadrant = 0;
};

}  // namespace

struct StripFiller::Impl {
  StripSetup setup;
  bool want_boundary = false, want_distance = false;
  std::vector<std::atomic<std::uint8_t>> seen;  // per site id
  std::atomic<std::int64_t> bad_site{-1};       // the first site id outside the table
  std::atomic<std::uint64_t> bad_distance{kNoCell};  // a cell whose distance the type cannot hold
  std::atomic<float> bad_distance_value{0};
  StripTimes times;

  // The strip's labels, and where they lie.
  LabelSpans spans;
  std::vector<std::int32_t> site;
  std::vector<float> metres;
  std::vector<std::uint8_t> boundary;

  // lon/lat: the pixel centres' longitudes (degrees, in [-180, 180)), the runs of them in one
  // quadrant and the quadrants they fall in, and (when labelled by pixel) the strip's rows'
  // latitudes.
  std::vector<double> lon;
  std::vector<QuadrantRun> runs;
  unsigned quadrants = 0;
  std::vector<double> strip_lat;

  explicit Impl(const StripSetup& s) : setup(s), seen(s.fid_of->size()) {
    want_boundary = has_band(s.bands, RasterBand::boundary);
    want_distance = has_band(s.bands, RasterBand::distance);
    for (auto& flag : seen) flag.store(0, std::memory_order_relaxed);
    if (setup.layout == RasterGrid::Layout::lonlat) {
      lon.resize(static_cast<std::size_t>(setup.size.width));
      for (std::size_t x = 0; x < lon.size(); ++x) {
        lon[x] = grid::normalise_lon(-180.0 + (static_cast<double>(x) + 0.5) * setup.size.x_resolution);
        const int q = grid::ParallelCells::quadrant_of(lon[x]);
        quadrants |= 1u << q;
        if (runs.empty() || runs.back().quadrant != q) runs.push_back({x, x, q});
        runs.back().end = x + 1;
      }
    }
  }

  int level() const { return setup.level; }
  std::size_t width() const { return static_cast<std::size_t>(setup.size.width); }
  /// Latitude (degrees) of pixel row y's centres.
  double row_latitude(int y) const { return 90.0 - (y + 0.5) * setup.size.y_resolution; }

  // The QTM-coded raster: pixel row octant * 2^L + i holds codes [o * 4^L + i^2, o * 4^L + (i + 1)^2).
  std::uint64_t qtm_row(int y) const { return static_cast<std::uint64_t>(y) & (grid::rows_per_octant(level()) - 1); }
  Code qtm_row_start(int y) const {
    const std::uint64_t octant = static_cast<std::uint64_t>(y) >> level();
    const std::uint64_t i = qtm_row(y);
    return octant * grid::cells_per_octant(level()) + i * i;
  }

  void resize_labels(std::uint64_t count) {
    site.resize(count);
    if (want_boundary) boundary.resize(count);
    if (want_distance) metres.resize(count);
  }
  std::uint8_t* boundary_at(std::uint64_t k) { return want_boundary ? boundary.data() + k : nullptr; }
  float* metres_at(std::uint64_t k) { return want_distance ? metres.data() + k : nullptr; }

  /// The labels of the strip's cells, and their spans.
  void label_strip(int y0, int rows);
  void label_lonlat_rows(int y0, int rows);
  /// The code of the cell whose labels are at index k.
  Code code_at(std::uint64_t k) const;

  /// The index of each pixel's labels in row y0 + r of the strip from y0 (kNoCell: nodata).
  void row_index(int y0, int r, std::uint64_t* index) const;

  template <typename T>
  void put_values(int y0, int rows, T* buffer);
  template <typename T>
  void put_row(const std::uint64_t* index, T* out, std::size_t band_space);
};

void StripFiller::Impl::label_strip(int y0, int rows) {
  spans = LabelSpans{};
  if (setup.layout == RasterGrid::Layout::lonlat) {
    label_lonlat_rows(y0, rows);
    return;
  }
  // Rows of the QTM-coded raster: one range of codes, since an octant's last row ends where the
  // next octant's first row begins.
  const int last = y0 + rows - 1;
  LabelSpans::Span& span = spans.by_octant[0];
  span.first = qtm_row_start(y0);
  span.count = qtm_row_start(last) + 2 * qtm_row(last) + 1 - span.first;
  resize_labels(span.count);
  const double t = now_seconds();
  setup.source->label_range(span.first, span.count, site.data(), metres_at(0), boundary_at(0));
  times.labels += now_seconds() - t;
}

void StripFiller::Impl::label_lonlat_rows(int y0, int rows) {
  double t = now_seconds();
  // The rows of each octant that the strip's pixel centres fall in: a row of pixel centres is a
  // parallel, one row of cells in each octant of its hemisphere that its longitudes reach.
  std::uint64_t lo[grid::kOctants], hi[grid::kOctants];
  for (int o = 0; o < grid::kOctants; ++o) lo[o] = ~std::uint64_t{0}, hi[o] = 0;
  for (int r = 0; r < rows; ++r) {
    const double lat = row_latitude(y0 + r);
    if (!(lat >= -90.0)) continue;  // centres past the pole: nodata
    const grid::ParallelCells parallel(lat, level());
    for (int q = 0; q < 4; ++q) {
      if ((quadrants >> q & 1u) == 0) continue;
      const int o = parallel.octant(q);
      lo[o] = std::min(lo[o], parallel.row());
      hi[o] = std::max(hi[o], parallel.row());
    }
  }
  std::uint64_t range_cells = 0;
  for (int o = 0; o < grid::kOctants; ++o) {
    if (lo[o] <= hi[o]) range_cells += (hi[o] + 1) * (hi[o] + 1) - lo[o] * lo[o];
  }
  // Where pixels are as fine as cells or finer (the strip's rows of cells, a band of latitude:
  // up to one range of codes in each octant, hold no more cells than the strip has pixels), the
  // rows are labelled whole: the painter labels each cell once, however many pixels it holds.
  // Coarser pixels are labelled along their rows' parallels, each pixel once: most lie in
  // leaves of one site and are filled run by run (at 0.025 degrees and level 12, where the rows
  // hold 2.6 cells a pixel at the equator, the parallels took no more time than the rows).
  const std::uint64_t pixels = static_cast<std::uint64_t>(rows) * width();
  if (range_cells <= pixels) {
    std::uint64_t total = 0;
    for (int o = 0; o < grid::kOctants; ++o) {
      if (lo[o] > hi[o]) continue;
      LabelSpans::Span& span = spans.by_octant[o];
      span.first = static_cast<Code>(o) * grid::cells_per_octant(level()) + lo[o] * lo[o];
      span.count = (hi[o] + 1) * (hi[o] + 1) - lo[o] * lo[o];
      span.offset = total;
      total += span.count;
    }
    resize_labels(total);
    times.cells += now_seconds() - t;
    t = now_seconds();
    for (const LabelSpans::Span& span : spans.by_octant) {
      if (span.count == 0) continue;
      setup.source->label_range(span.first, span.count, site.data() + span.offset, metres_at(span.offset),
                                boundary_at(span.offset));
    }
    times.labels += now_seconds() - t;
    return;
  }
  // Coarser pixels: each pixel's labels, found along its row's parallel (the rows past latitude
  // -90, the strip's last if any, are nodata).
  strip_lat.clear();
  for (int r = 0; r < rows && row_latitude(y0 + r) >= -90.0; ++r) strip_lat.push_back(row_latitude(y0 + r));
  spans.by_pixel = true;
  spans.pixels = static_cast<std::uint64_t>(strip_lat.size()) * width();
  resize_labels(spans.pixels);
  times.cells += now_seconds() - t;
  t = now_seconds();
  setup.source->label_parallels(strip_lat.data(), static_cast<int>(strip_lat.size()), lon.data(), width(), site.data(), metres_at(0),
                                boundary_at(0));
  times.labels += now_seconds() - t;
}

Code StripFiller::Impl::code_at(std::uint64_t k) const {
  if (spans.by_pixel) {
    const std::uint64_t r = k / width();
    return grid::lonlat_to_code(lon[k - r * width()], strip_lat[r], level());
  }
  for (const LabelSpans::Span& s : spans.by_octant) {
    if (s.count > 0 && k >= s.offset && k - s.offset < s.count) return s.first + (k - s.offset);
  }
  return grid::kInvalidCode;
}

void StripFiller::Impl::row_index(int y0, int r, std::uint64_t* index) const {
  const std::size_t w = width();
  const int y = y0 + r;
  if (setup.layout == RasterGrid::Layout::qtm) {
    const std::uint64_t start = qtm_row_start(y) - spans.by_octant[0].first;
    const std::size_t cols = static_cast<std::size_t>(2 * qtm_row(y) + 1);
    for (std::size_t x = 0; x < cols; ++x) index[x] = start + x;
    std::fill(index + cols, index + w, kNoCell);
    return;
  }
  const double lat = row_latitude(y);
  if (!(lat >= -90.0)) {
    std::fill(index, index + w, kNoCell);
    return;
  }
  if (spans.by_pixel) {
    const std::uint64_t at = static_cast<std::uint64_t>(r) * w;
    for (std::size_t x = 0; x < w; ++x) index[x] = at + x;
    return;
  }
  // Along a run of one quadrant only the column changes: the labels' index of the row's column 0,
  // plus the column.
  const grid::ParallelCells parallel(lat, level());
  for (const QuadrantRun& run : runs) {
    const int o = parallel.octant(run.quadrant);
    const LabelSpans::Span& span = spans.by_octant[o];
    const Code row_start = grid::code_of({o, static_cast<std::uint32_t>(parallel.row()), 0}, level());
    const std::uint64_t at = span.offset + (row_start - span.first);
    for (std::size_t x = run.begin; x < run.end; ++x) index[x] = at + parallel.column(parallel.local_lon(run.quadrant, lon[x]));
  }
}

template <typename T>
void StripFiller::Impl::put_row(const std::uint64_t* index, T* out, std::size_t band_space) {
  const std::size_t w = width();
  const std::size_t sites = seen.size();
  const T nodata = static_cast<T>(setup.nodata);
  // Which sites the pixels show, and site ids outside the table.
  for (std::size_t x = 0; x < w; ++x) {
    if (index[x] == kNoCell) continue;
    const std::int32_t s = site[index[x]];
    if (static_cast<std::uint32_t>(s) >= sites) {
      std::int64_t none = -1;
      bad_site.compare_exchange_strong(none, s);
    } else if (seen[static_cast<std::size_t>(s)].load(std::memory_order_relaxed) == 0) {
      seen[static_cast<std::size_t>(s)].store(1, std::memory_order_relaxed);
    }
  }
  const std::vector<std::int64_t>& fid_of = *setup.fid_of;
  for (std::size_t b = 0; b < setup.bands.size(); ++b, out += band_space) {
    switch (setup.bands[b]) {
      case RasterBand::fid:
        for (std::size_t x = 0; x < w; ++x) {
          const std::uint64_t k = index[x];
          const std::int32_t s = k == kNoCell ? -1 : site[k];
          // Exact: every FID was checked against the type before writing.
          out[x] = static_cast<std::uint32_t>(s) < sites ? static_cast<T>(fid_of[static_cast<std::size_t>(s)]) : nodata;
        }
        break;
      case RasterBand::boundary:
        for (std::size_t x = 0; x < w; ++x) out[x] = index[x] == kNoCell ? nodata : static_cast<T>(boundary[index[x]]);
        break;
      case RasterBand::distance:
        if (!is_integer_type(setup.type)) {
          for (std::size_t x = 0; x < w; ++x) out[x] = index[x] == kNoCell ? nodata : static_cast<T>(metres[index[x]]);
          break;
        }
        for (std::size_t x = 0; x < w; ++x) {
          if (index[x] == kNoCell) {
            out[x] = nodata;
            continue;
          }
          const float d = metres[index[x]];
          const double whole = std::nearbyint(static_cast<double>(d));  // whole metres, ties to even
          if (whole >= 0 && whole <= largest_value(setup.type)) {
            out[x] = static_cast<T>(whole);
            continue;
          }
          out[x] = nodata;
          std::uint64_t none = kNoCell;
          if (bad_distance.compare_exchange_strong(none, code_at(index[x]))) bad_distance_value.store(d);
        }
        break;
    }
  }
}

template <typename T>
void StripFiller::Impl::put_values(int y0, int rows, T* buffer) {
  const std::size_t w = width();
  const std::size_t band_space = w * static_cast<std::size_t>(rows);
#pragma omp parallel num_threads(setup.threads)
  {
    std::vector<std::uint64_t> index(w);
#pragma omp for schedule(dynamic, 4)
    for (int r = 0; r < rows; ++r) {
      row_index(y0, r, index.data());
      put_row(index.data(), buffer + static_cast<std::size_t>(r) * w, band_space);
    }
  }
}

StripFiller::StripFiller(const StripSetup& setup) : impl_(std::make_unique<Impl>(setup)) {}
StripFiller::~StripFiller() = default;

void StripFiller::fill(int y0, int rows, void* buffer) {
  Impl& s = *impl_;
  s.label_strip(y0, rows);
  const double t = now_seconds();
  switch (s.setup.type) {
    case GDT_Byte: s.put_values(y0, rows, static_cast<std::uint8_t*>(buffer)); break;
    case GDT_UInt16: s.put_values(y0, rows, static_cast<std::uint16_t*>(buffer)); break;
    case GDT_Int16: s.put_values(y0, rows, static_cast<std::int16_t*>(buffer)); break;
    case GDT_UInt32: s.put_values(y0, rows, static_cast<std::uint32_t*>(buffer)); break;
    case GDT_Int32: s.put_values(y0, rows, static_cast<std::int32_t*>(buffer)); break;
    case GDT_Float32: s.put_values(y0, rows, static_cast<float*>(buffer)); break;
    default: s.put_values(y0, rows, static_cast<double*>(buffer)); break;
  }
  s.times.values += now_seconds() - t;
}

void StripFiller::check(const std::string& path) const {
  const Impl& s = *impl_;
  const auto band_label = [&](RasterBand band) {
    const auto at = std::find(s.setup.bands.begin(), s.setup.bands.end(), band) - s.setup.bands.begin();
    return "band " + std::to_string(at + 1) + " (" + raster_band_description(band) + ")";
  };
  if (s.bad_site >= 0) {
    const bool fid = has_band(s.setup.bands, RasterBand::fid);
    throw WriteError(path + ": " + (fid ? band_label(RasterBand::fid) : std::string("labels")) + ": site id " + std::to_string(s.bad_site.load()) +
                     " is not in the site table (" + std::to_string(s.seen.size()) + " sites)");
  }
  if (s.bad_distance != kNoCell) {
    char metres[64];
    std::snprintf(metres, sizeof metres, "%.1f", static_cast<double>(s.bad_distance_value.load()));
    throw WriteError(path + ": " + band_label(RasterBand::distance) + ": cell " + std::to_string(s.bad_distance.load()) +
                     " is " + metres + " m from its site, outside " + GDALGetDataTypeName(s.setup.type) + " (" +
                     range_text(s.setup.type) + "; distances are rounded to whole metres): choose a wider -ot, e.g. " +
                     "UInt32, Int32 or Float32");
  }
}

std::vector<std::uint8_t> StripFiller::site_seen() const {
  const Impl& s = *impl_;
  std::vector<std::uint8_t> out(s.seen.size());
  for (std::size_t k = 0; k < out.size(); ++k) out[k] = s.seen[k].load(std::memory_order_relaxed);
  return out;
}

const StripTimes& StripFiller::times() const { return impl_->times; }

std::uint64_t StripFiller::bytes_per_pixel(RasterGrid::Layout layout, const std::vector<RasterBand>& bands) {
  const std::uint64_t labels = sizeof(std::int32_t) + (has_band(bands, RasterBand::distance) ? sizeof(float) : 0) +
                               (has_band(bands, RasterBand::boundary) ? 1 : 0);
  return layout == RasterGrid::Layout::lonlat ? 2 * sizeof(Code) + 4 * labels : labels;
}

}  // namespace qtmv::write
