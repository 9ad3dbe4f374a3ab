#include "write/gpkg_rtree.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <utility>

#include "common/openmp_threads.hpp"
#include "common/parallel_sort.hpp"
#include "common/radix_sort.hpp"
#include "write/sqlite_statement.hpp"

namespace qtmv::write {
namespace {

constexpr std::size_t kCellBytes = 8 + 4 * 4;  // id, then min x, max x, min y, max y (float32)
constexpr std::size_t kNodeHeader = 4;         // depth (root only), cell count
// SQLite's rounding of a double bound to float32 (rtree.c): scaled by one float ulp towards or
// away from zero when the nearest float lies on the wrong side.
constexpr double kTowardsZero = 1.0 - 1.0 / 8388608.0;
constexpr double kAwayFromZero = 1.0 + 1.0 / 8388608.0;

float rounded_down(double d) {
  float f = static_cast<float>(d);
  if (f > d) f = static_cast<float>(d * (d < 0 ? kAwayFromZero : kTowardsZero));
  return f;
}

float rounded_up(double d) {
  float f = static_cast<float>(d);
  if (f < d) f = static_cast<float>(d * (d < 0 ? kTowardsZero : kAwayFromZero));
  return f;
}

/// A box in the tree being packed: a row's entry in a leaf, or a node one level up (its id then
/// the node's index in its level).
using Box = RTreeEntry;

double centre_x(const Box& b) { return (static_cast<double>(b.min_x) + b.max_x) / 2; }
double centre_y(const Box& b) { return (static_cast<double>(b.min_y) + b.max_y) / 2; }

/// A node: its box and its children, a run of the level below.
struct Node {
  Box box;
  std::size_t first, count;
};

/// Sorts items[first, last) by centre (centre_x or centre_y), ties by id: through an array of
/// the centres and places, so that a comparison reads 16 bytes and computes nothing.
template <class Centre>
void sort_by_centre(std::vector<Box>& items, std::size_t first, std::size_t last, Centre centre, bool parallel) {
  struct Keyed {
    double centre;
    std::size_t place;
  };
  std::vector<Keyed> keyed(last - first);
  for (std::size_t k = first; k < last; ++k) keyed[k - first] = {centre(items[k]), k};
  const auto less = [&items](const Keyed& a, const Keyed& b) {
    return a.centre < b.centre || (a.centre == b.centre && items[a.place].id < items[b.place].id);
  };
  if (parallel) {
    parallel_sort(keyed.begin(), keyed.end(), less);
  } else {
    std::sort(keyed.begin(), keyed.end(), less);
  }
  std::vector<Box> sorted(last - first);
  for (std::size_t k = 0; k < keyed.size(); ++k) sorted[k] = items[keyed[k].place];
  std::copy(sorted.begin(), sorted.end(), items.begin() + static_cast<std::ptrdiff_t>(first));
}

/// Packs `items` into nodes of up to `capacity` (Sort-Tile-Recursive: vertical slices by the
/// boxes' centres in x, each sorted in y and cut into full nodes). Reorders `items` so that each
/// node's children are a run; ties are broken by id, so the packing is deterministic.
std::vector<Node> pack(std::vector<Box>& items, std::size_t capacity) {
  const std::size_t nodes = (items.size() + capacity - 1) / capacity;
  const auto slices = static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(nodes))));
  const std::size_t per_slice = slices * capacity;
  // Ids are unique, so both orders are total: the same packing on any number of threads.
  sort_by_centre(items, 0, items.size(), centre_x, true);
  const std::size_t slice_count = (items.size() + per_slice - 1) / per_slice;
#pragma omp parallel for schedule(dynamic, 1) num_threads(thread_count(0))
  for (std::int64_t slice = 0; slice < static_cast<std::int64_t>(slice_count); ++slice) {
    const std::size_t first = static_cast<std::size_t>(slice) * per_slice;
    sort_by_centre(items, first, std::min(items.size(), first + per_slice), centre_y, false);
  }
  // Full nodes, each slice's from its start: node k of slice s covers its items from s * per_slice.
  std::vector<Node> out;
  out.reserve(nodes);
  for (std::size_t slice = 0; slice < items.size(); slice += per_slice) {
    const std::size_t end = std::min(items.size(), slice + per_slice);
    for (std::size_t first = slice; first < end; first += capacity) {
      out.push_back({items[first], first, std::min(capacity, end - first)});
    }
  }
#pragma omp parallel for schedule(static) num_threads(thread_count(0))
  for (std::int64_t k = 0; k < static_cast<std::int64_t>(out.size()); ++k) {
    Node& node = out[static_cast<std::size_t>(k)];
    Box& box = node.box;
    for (std::size_t c = node.first + 1; c < node.first + node.count; ++c) {
      box.min_x = std::min(box.min_x, items[c].min_x);
      box.max_x = std::max(box.max_x, items[c].max_x);
      box.min_y = std::min(box.min_y, items[c].min_y);
      box.max_y = std::max(box.max_y, items[c].max_y);
    }
    box.id = k;
  }
  return out;
}

unsigned char* put_be(unsigned char* out, std::uint64_t v, int bytes) {
  for (int k = bytes - 1; k >= 0; --k) *out++ = static_cast<unsigned char>(v >> (8 * k));
  return out;
}

unsigned char* put_cell(unsigned char* out, std::int64_t id, const Box& box) {
  out = put_be(out, static_cast<std::uint64_t>(id), 8);
  for (float v : {box.min_x, box.max_x, box.min_y, box.max_y}) {
    std::uint32_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    out = put_be(out, bits, 4);
  }
  return out;
}

/// Rows of two integers into a table, kPairsPerStatement to an INSERT.
class PairInserter {
 public:
  PairInserter(sqlite3* db, const std::string& table, const std::string& columns, std::string what)
      : insert_(db, "INSERT INTO " + table + " (" + columns + ") VALUES ", 2, kPairsPerStatement), what_(std::move(what)) {
    pending_.reserve(2 * kPairsPerStatement);
  }
  void add(std::int64_t a, std::int64_t b) {
    pending_.push_back(a);
    pending_.push_back(b);
    if (pending_.size() == 2 * kPairsPerStatement) flush();
  }
  void flush() {
    if (pending_.empty()) return;
    sqlite3_stmt* statement = insert_.prepare(pending_.size() / 2);
    for (std::size_t k = 0; k < pending_.size(); ++k) sqlite3_bind_int64(statement, static_cast<int>(k + 1), pending_[k]);
    insert_.run(what_);
    pending_.clear();
  }

 private:
  static constexpr std::size_t kPairsPerStatement = 256;  // 512 parameters: under any SQLite's limit
  MultiRowInsert insert_;
  std::string what_;
  std::vector<std::int64_t> pending_;
};

}  // namespace

RTreeEntry rtree_entry(std::int64_t id, double min_x, double max_x, double min_y, double max_y) {
  return {id, rounded_down(min_x), rounded_up(max_x), rounded_down(min_y), rounded_up(max_y)};
}

void bulk_load_rtree(sqlite3* db, const std::string& name, std::vector<RTreeEntry> entries) {
  const std::string where = "R-tree " + quoted(name);
  const auto node_table = quoted(name + "_node"), rowid_table = quoted(name + "_rowid");
  const auto parent_table = quoted(name + "_parent");
  if (Statement(db, "SELECT count(*) FROM " + rowid_table).integer() != 0 ||
      Statement(db, "SELECT count(*) FROM " + node_table).integer() != 1) {
    throw WriteError(where + " is not empty: it cannot be loaded at once");
  }
  const auto node_size = static_cast<std::size_t>(Statement(db, "SELECT length(data) FROM " + node_table + " WHERE nodeno = 1").integer());
  const std::size_t capacity = node_size > kNodeHeader ? (node_size - kNodeHeader) / kCellBytes : 0;
  if (capacity < 2 || capacity > 0xffff) throw WriteError(where + ": unexpected node size " + std::to_string(node_size));
  if (entries.empty()) return;

  // Levels from the leaves up: levels[0] are the leaves, whose children are the entries.
  std::vector<Box>& items = entries;
  std::vector<std::vector<Node>> levels;
  std::vector<Box> boxes;  // the current level's nodes as items of the level above
  levels.push_back(pack(items, capacity));
  while (levels.back().size() > 1) {
    boxes.clear();
    for (const Node& n : levels.back()) boxes.push_back(n.box);
    std::vector<Node> above = pack(boxes, capacity);
    // pack() reordered the boxes: put the nodes of this level in the same order.
    std::vector<Node> reordered;
    reordered.reserve(boxes.size());
    for (const Box& b : boxes) reordered.push_back(levels.back()[static_cast<std::size_t>(b.id)]);
    levels.back() = std::move(reordered);
    levels.push_back(std::move(above));
  }

  // Node numbers: the root 1, then level by level downwards; node k of level l is first[l] + k.
  std::vector<std::int64_t> first(levels.size());
  std::int64_t next = 1;
  for (std::size_t l = levels.size(); l-- > 0;) {
    first[l] = next;
    next += static_cast<std::int64_t>(levels[l].size());
  }

  // Writing into the shadow tables is refused in SQLite's defensive mode: off while loading.
  int defensive = 0;
  sqlite3_db_config(db, SQLITE_DBCONFIG_DEFENSIVE, -1, &defensive);
  if (defensive) sqlite3_db_config(db, SQLITE_DBCONFIG_DEFENSIVE, 0, nullptr);
  struct Restore {
    sqlite3* db;
    int defensive;
    ~Restore() {
      if (defensive) sqlite3_db_config(db, SQLITE_DBCONFIG_DEFENSIVE, 1, nullptr);
    }
  } restore{db, defensive};

  Statement root(db, "UPDATE " + node_table + " SET data = ?1 WHERE nodeno = 1");
  Statement node(db, "INSERT INTO " + node_table + " (nodeno, data) VALUES (?1, ?2)");
  PairInserter parent(db, parent_table, "nodeno, parentnode", "write a node's parent in " + where);
  // Each row's leaf, written in rowid order after the nodes: appended to the rowid table's
  // B-tree, where the leaves' order (by place) would insert all over it, a page read and a page
  // written back per row once the table outgrows SQLite's page cache.
  std::vector<std::pair<std::int64_t, std::int64_t>> leaf_of;
  leaf_of.reserve(items.size());
  const std::string write_node = "write a node of " + where;
  std::vector<unsigned char> blob(node_size);
  for (std::size_t l = levels.size(); l-- > 0;) {
    for (std::size_t k = 0; k < levels[l].size(); ++k) {
      const Node& n = levels[l][k];
      const std::int64_t nodeno = first[l] + static_cast<std::int64_t>(k);
      std::fill(blob.begin(), blob.end(), 0);
      unsigned char* out = put_be(blob.data(), nodeno == 1 ? levels.size() - 1 : 0, 2);
      out = put_be(out, n.count, 2);
      for (std::size_t c = n.first; c < n.first + n.count; ++c) {
        if (l == 0) {
          out = put_cell(out, items[c].id, items[c]);
          leaf_of.emplace_back(items[c].id, nodeno);
        } else {
          const std::int64_t child = first[l - 1] + static_cast<std::int64_t>(c);
          out = put_cell(out, child, levels[l - 1][c].box);
          parent.add(child, nodeno);
        }
      }
      Statement& statement = nodeno == 1 ? root : node;
      const int blob_parameter = nodeno == 1 ? 1 : 2;
      if (nodeno != 1) sqlite3_bind_int64(node.get(), 1, nodeno);
      sqlite3_bind_blob(statement.get(), blob_parameter, blob.data(), static_cast<int>(blob.size()), SQLITE_STATIC);
      statement.run(write_node);
      if (nodeno == 1 && sqlite3_changes(db) != 1) throw WriteError(where + ": no root node");
    }
  }
  parent.flush();
  const auto [lowest, highest] = std::minmax_element(leaf_of.begin(), leaf_of.end());
  if (lowest->first >= 0) {  // GeoPackage's FIDs: a radix sort on their bits
    radix_sort(leaf_of, bits_for(static_cast<std::uint64_t>(highest->first)),
               [](const std::pair<std::int64_t, std::int64_t>& row) { return static_cast<std::uint64_t>(row.first); });
  } else {
    parallel_sort(leaf_of.begin(), leaf_of.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  }
  PairInserter rowid(db, rowid_table, "rowid, nodeno", "write a row's leaf in " + where);
  for (const auto& [id, leaf] : leaf_of) rowid.add(id, leaf);
  rowid.flush();
}

}  // namespace qtmv::write
