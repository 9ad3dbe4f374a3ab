// The reader's results compared whole (tests/sites): every array of the geometry, the site table
// (FIDs, kinds, counts, attributes), the summary's counts and the messages, for reads with
// different thread counts or ways of reading.
#pragma once

#include <gtest/gtest.h>

#include <ogr_srs_api.h>

#include <cstring>
#include <string>
#include <vector>

#include "sites/ogr_site_reader.hpp"
#include "sites_test_support.hpp"

namespace qtmv::sites::test {

struct Read {
  SiteSet set;
  std::vector<std::string> messages;
};

inline Read read_with(const std::string& path, ReadOptions options, int threads) {
  // OGR keeps the transformations a read destroys and hands them to the next, with the count of
  // failures they have reported (after 20 they say no more): each read starts afresh.
  OSRCleanup();
  Read out;
  options.threads = threads;
  options.messages = [&out](Severity, const std::string& m) { out.messages.push_back(m); };
  out.set = read_sites(path, options);
  return out;
}

/// Whether two reads' features have the same FID and fields (OGRFeature::Equal also asks for the
/// same definition object).
inline bool same_fields(const OGRFeature* a, const OGRFeature* b) {
  if (!a || !b || a->GetFID() != b->GetFID() || a->GetFieldCount() != b->GetFieldCount()) return false;
  for (int k = 0; k < a->GetFieldCount(); ++k) {
    if (a->IsFieldSetAndNotNull(k) != b->IsFieldSetAndNotNull(k) ||
        a->GetFieldDefnRef(k)->GetType() != b->GetFieldDefnRef(k)->GetType() ||
        std::strcmp(a->GetFieldAsString(k), b->GetFieldAsString(k)) != 0) {
      return false;
    }
  }
  return true;
}

/// Every array, element by element; the site table; the summary's counts; the messages.
inline void expect_same(const Read& a, const Read& b) {
  expect_same_geometry(a.set.geometry, b.set.geometry);
  const std::vector<SiteRecord>&r = a.set.table.sites, &s = b.set.table.sites;
  ASSERT_EQ(r.size(), s.size());
  std::size_t differ = 0;
  for (std::size_t k = 0; k < r.size(); ++k) {
    differ += r[k].fid != s[k].fid || r[k].kind != s[k].kind || r[k].site_cells != s[k].site_cells ||
              r[k].fixed_cells != s[k].fixed_cells || r[k].has_own_cell != s[k].has_own_cell ||
              r[k].layer != s[k].layer || !same_fields(r[k].attributes.get(), s[k].attributes.get());
  }
  EXPECT_EQ(differ, 0u) << "site records differ";
  const ReadSummary &u = a.set.summary, &v = b.set.summary;
  EXPECT_EQ(u.features, v.features);
  EXPECT_EQ(u.sites, v.sites);
  EXPECT_EQ(u.skipped, v.skipped);
  EXPECT_EQ(u.skipped_coordinate, v.skipped_coordinate);
  EXPECT_EQ(u.skipped_transform, v.skipped_transform);
  EXPECT_EQ(u.invalid_polygons, v.invalid_polygons);
  EXPECT_EQ(u.repaired_polygons, v.repaired_polygons);
  EXPECT_EQ(u.sites_without_own_cell, v.sites_without_own_cell);
  EXPECT_EQ(u.vertex_steps, v.vertex_steps);
  EXPECT_EQ(u.wrapped_features, v.wrapped_features);
  EXPECT_EQ(a.messages, b.messages);
}

/// Reads `path` with 1, 2 and 8 threads and expects the same of each; returns the one thread's.
inline Read same_with_any_threads(const std::string& path, const ReadOptions& options) {
  Read one = read_with(path, options, 1);
  for (const int threads : {2, 8}) {
    SCOPED_TRACE(std::to_string(threads) + " threads");
    expect_same(one, read_with(path, options, threads));
  }
  return one;
}

}  // namespace qtmv::sites::test
