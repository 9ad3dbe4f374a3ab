// The labeller's CUDA kernels and launches. The maths is the QTMV_HD code of src/label
// (label_math.hpp, label_tree.hpp), compiled here without FMA contraction (qtmv::grid adds
// --fmad=false), so the labels are those of the CPU path bit for bit.
#include <cuda_runtime.h>

#include <stdexcept>
#include <string>

#include "label/label_cuda.hpp"
#include "label/label_tree.hpp"
#include "label/labeller.hpp"

namespace qtmv::label::cuda {

namespace {

/// Throws std::runtime_error naming the failed call and its place in the source.
void check(cudaError_t status, const char* call, const char* file, int line) {
  if (status != cudaSuccess) {
    throw std::runtime_error(std::string("CUDA error ") + cudaGetErrorName(status) + " (" +
                             cudaGetErrorString(status) + ") in " + call + " at " + file + ":" +
                             std::to_string(line));
  }
}
#define QTMV_CUDA_CHECK(call) check((call), #call, __FILE__, __LINE__)
/// After a kernel launch: launch errors now, execution errors at the next synchronisation.
#define QTMV_CUDA_CHECK_LAUNCH(name) check(cudaGetLastError(), "launch of " name, __FILE__, __LINE__)

constexpr int kBlock = 256;

unsigned int blocks_for(std::uint64_t count) {
  const std::uint64_t blocks = (count + kBlock - 1) / kBlock;
  return static_cast<unsigned int>(blocks < 0x7fffffffu ? blocks : 0x7fffffffu);
}

// --- hier -----------------------------------------------------------------------------------

__global__ void tree_label_kernel(TreeView tree, grid::Code first, std::uint64_t count, std::int32_t* site,
                                  float* metres, std::uint8_t* boundary) {
  const std::uint64_t stride = static_cast<std::uint64_t>(gridDim.x) * blockDim.x;
  for (std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x; k < count; k += stride) {
    tree_label_cell(tree, first + k, site + k, metres ? metres + k : nullptr, boundary ? boundary + k : nullptr);
  }
}

// --- brute: the paper's Kernel Function 1, candidates tiled through shared memory ----------

__global__ void brute_label_kernel(const Piece* pieces, int piece_count, int level, grid::Code first,
                                   std::uint64_t count, std::int32_t* site, float* metres) {
  __shared__ Piece tile[kBlock];
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  const bool active = k < count;
  const Vec3 x = grid::cell_centre_vector(active ? first + k : first, level);
  Best best = no_best();
  for (int base = 0; base < piece_count; base += kBlock) {
    const int n = piece_count - base < kBlock ? piece_count - base : kBlock;
    __syncthreads();
    if (static_cast<int>(threadIdx.x) < n) tile[threadIdx.x] = pieces[base + threadIdx.x];
    __syncthreads();
    for (int p = 0; p < n; ++p) consider(best, piece_chord2(x, tile[p]), tile[p]);
  }
  if (!active) return;
  site[k] = best.site;
  if (metres) metres[k] = static_cast<float>(chord2_to_metres(best.chord2));
}

/// Boundary flags from the labels of [first, first + count); neighbours outside the range are
/// labelled again by brute force (only the tile's edges).
__global__ void brute_boundary_kernel(const Piece* pieces, int piece_count, int level, grid::Code first,
                                      std::uint64_t count, const std::int32_t* site, std::uint8_t* boundary) {
  const std::uint64_t stride = static_cast<std::uint64_t>(gridDim.x) * blockDim.x;
  for (std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x; k < count; k += stride) {
    grid::Cell nb[3];
    grid::neighbours(fast_cell_of(first + k, level), level, nb);
    std::uint8_t flag = 0;
    for (int s = 0; s < 3 && !flag; ++s) {
      const grid::Code code = grid::code_of(nb[s], level);
      std::int32_t other;
      if (code >= first && code - first < count) {
        other = site[code - first];
      } else {
        const Vec3 x = grid::cell_centre_vector(code, level);
        Best best = no_best();
        for (int p = 0; p < piece_count; ++p) consider(best, piece_chord2(x, pieces[p]), pieces[p]);
        other = best.site;
      }
      flag = other != site[k];
    }
    boundary[k] = flag;
  }
}

/// The float64 brute-force label of each code of a list (the benchmark's reference).
__global__ void brute_codes_kernel(const Piece* pieces, int piece_count, int level, const grid::Code* codes,
                                   std::uint64_t count, std::int32_t* site) {
  __shared__ Piece tile[kBlock];
  const std::uint64_t k = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  const bool active = k < count;
  const Vec3 x = grid::cell_centre_vector(active ? codes[k] : 0, level);
  Best best = no_best();
  for (int base = 0; base < piece_count; base += kBlock) {
    const int n = piece_count - base < kBlock ? piece_count - base : kBlock;
    __syncthreads();
    if (static_cast<int>(threadIdx.x) < n) tile[threadIdx.x] = pieces[base + threadIdx.x];
    __syncthreads();
    for (int p = 0; p < n; ++p) consider(best, piece_chord2(x, tile[p]), tile[p]);
  }
  if (active) site[k] = best.site;
}

template <typename T>
T* device_alloc(std::size_t count, std::size_t* total) {
  T* p = nullptr;
  if (count == 0) return p;
  QTMV_CUDA_CHECK(cudaMalloc(&p, count * sizeof(T)));
  *total += count * sizeof(T);
  return p;
}

template <typename T>
T* device_copy(const std::vector<T>& host, std::size_t* total) {
  T* p = device_alloc<T>(host.size(), total);
  if (p) QTMV_CUDA_CHECK(cudaMemcpy(p, host.data(), host.size() * sizeof(T), cudaMemcpyHostToDevice));
  return p;
}

}  // namespace

int device_count() {
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess) {
    (void)cudaGetLastError();  // no driver or no device: not an error here, just none
    return 0;
  }
  return count;
}

DeviceInfo device_info(int device) {
  cudaDeviceProp prop{};
  QTMV_CUDA_CHECK(cudaGetDeviceProperties(&prop, device));
  QTMV_CUDA_CHECK(cudaSetDevice(device));
  DeviceInfo info;
  info.name = prop.name;
  QTMV_CUDA_CHECK(cudaMemGetInfo(&info.free_bytes, &info.total_bytes));
  return info;
}

struct Labeller::Impl {
  int device = 0;
  int level = 0;
  bool hier = false;
  int piece_count = 0;
  Piece* pieces = nullptr;
  TreeNode* nodes = nullptr;
  std::int32_t* lists = nullptr;
  JumpEntry* jump = nullptr;
  int jump_level = 0;
  std::int32_t* site = nullptr;
  float* metres = nullptr;
  std::uint8_t* boundary = nullptr;
  std::uint64_t capacity = 0;
  std::size_t bytes = 0;
  std::size_t output_bytes = 0;
  cudaEvent_t start = nullptr, stop = nullptr;

  void free_outputs() {
    cudaFree(site);
    cudaFree(metres);
    cudaFree(boundary);
    site = nullptr;
    metres = nullptr;
    boundary = nullptr;
    bytes -= output_bytes;
    output_bytes = 0;
    capacity = 0;
  }
  ~Impl() {
    // Destructors must not throw; errors here are left to the next call's check.
    free_outputs();
    cudaFree(pieces);
    cudaFree(nodes);
    cudaFree(lists);
    cudaFree(jump);
    if (start) cudaEventDestroy(start);
    if (stop) cudaEventDestroy(stop);
  }
};

Labeller::Labeller(int device, const std::vector<Piece>& candidates, const Tree* tree, int level)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.device = device;
  m.level = level;
  m.hier = tree != nullptr;
  QTMV_CUDA_CHECK(cudaSetDevice(device));
  QTMV_CUDA_CHECK(cudaEventCreate(&m.start));
  QTMV_CUDA_CHECK(cudaEventCreate(&m.stop));
  if (candidates.size() > 0x7fffffffu) throw std::invalid_argument("more than 2^31 candidates");
  m.piece_count = static_cast<int>(candidates.size());
  m.pieces = device_copy(candidates, &m.bytes);
  if (tree) {
    m.nodes = device_copy(tree->nodes, &m.bytes);
    m.lists = device_copy(tree->lists, &m.bytes);
    m.jump = device_copy(tree->jump, &m.bytes);
    m.jump_level = tree->jump_level;
  }
}

Labeller::~Labeller() = default;

void Labeller::reserve(std::uint64_t max_cells, bool want_distance, bool want_boundary) {
  Impl& m = *impl_;
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  m.free_outputs();
  const std::size_t before = m.bytes;
  m.site = device_alloc<std::int32_t>(max_cells, &m.bytes);
  // brute needs the labels of a whole tile for its boundary pass; distances on request.
  if (want_distance) m.metres = device_alloc<float>(max_cells, &m.bytes);
  if (want_boundary) m.boundary = device_alloc<std::uint8_t>(max_cells, &m.bytes);
  m.output_bytes = m.bytes - before;
  m.capacity = max_cells;
}

float Labeller::run(grid::Code first, std::uint64_t count, bool want_distance, bool want_boundary) {
  Impl& m = *impl_;
  if (count > m.capacity) throw std::invalid_argument("Labeller::run: more cells than reserved");
  if ((want_distance && !m.metres) || (want_boundary && !m.boundary)) {
    throw std::invalid_argument("Labeller::run: outputs asked for that reserve() did not make room for");
  }
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  float* metres = want_distance ? m.metres : nullptr;
  std::uint8_t* boundary = want_boundary ? m.boundary : nullptr;
  QTMV_CUDA_CHECK(cudaEventRecord(m.start));
  if (m.hier) {
    const TreeView view{m.nodes, m.lists, m.pieces, m.jump, m.jump_level, m.level};
    tree_label_kernel<<<blocks_for(count), kBlock>>>(view, first, count, m.site, metres, boundary);
    QTMV_CUDA_CHECK_LAUNCH("tree_label_kernel");
  } else {
    brute_label_kernel<<<blocks_for(count), kBlock>>>(m.pieces, m.piece_count, m.level, first, count, m.site, metres);
    QTMV_CUDA_CHECK_LAUNCH("brute_label_kernel");
    if (boundary) {
      brute_boundary_kernel<<<blocks_for(count), kBlock>>>(m.pieces, m.piece_count, m.level, first, count, m.site,
                                                            boundary);
      QTMV_CUDA_CHECK_LAUNCH("brute_boundary_kernel");
    }
  }
  QTMV_CUDA_CHECK(cudaEventRecord(m.stop));
  QTMV_CUDA_CHECK(cudaEventSynchronize(m.stop));
  float ms = 0;
  QTMV_CUDA_CHECK(cudaEventElapsedTime(&ms, m.start, m.stop));
  return ms;
}

float Labeller::download(std::uint64_t offset, std::uint64_t count, std::int32_t* site, float* distance_m,
                         std::uint8_t* boundary) {
  Impl& m = *impl_;
  if (offset + count > m.capacity) throw std::invalid_argument("Labeller::download: outside the reserved cells");
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  QTMV_CUDA_CHECK(cudaEventRecord(m.start));
  if (site) QTMV_CUDA_CHECK(cudaMemcpy(site, m.site + offset, count * sizeof(std::int32_t), cudaMemcpyDeviceToHost));
  if (distance_m && m.metres) {
    QTMV_CUDA_CHECK(cudaMemcpy(distance_m, m.metres + offset, count * sizeof(float), cudaMemcpyDeviceToHost));
  }
  if (boundary && m.boundary) {
    QTMV_CUDA_CHECK(cudaMemcpy(boundary, m.boundary + offset, count, cudaMemcpyDeviceToHost));
  }
  QTMV_CUDA_CHECK(cudaEventRecord(m.stop));
  QTMV_CUDA_CHECK(cudaEventSynchronize(m.stop));
  float ms = 0;
  QTMV_CUDA_CHECK(cudaEventElapsedTime(&ms, m.start, m.stop));
  return ms;
}

std::vector<std::int32_t> Labeller::brute_sites(const std::vector<grid::Code>& codes) {
  Impl& m = *impl_;
  QTMV_CUDA_CHECK(cudaSetDevice(m.device));
  std::size_t scratch = 0;
  grid::Code* d_codes = device_copy(codes, &scratch);
  std::int32_t* d_sites = device_alloc<std::int32_t>(codes.size(), &scratch);
  std::vector<std::int32_t> sites(codes.size());
  if (!codes.empty()) {
    brute_codes_kernel<<<blocks_for(codes.size()), kBlock>>>(m.pieces, m.piece_count, m.level, d_codes, codes.size(),
                                                             d_sites);
    QTMV_CUDA_CHECK_LAUNCH("brute_codes_kernel");
    QTMV_CUDA_CHECK(cudaMemcpy(sites.data(), d_sites, codes.size() * sizeof(std::int32_t), cudaMemcpyDeviceToHost));
  }
  QTMV_CUDA_CHECK(cudaFree(d_codes));
  QTMV_CUDA_CHECK(cudaFree(d_sites));
  return sites;
}

std::size_t Labeller::device_bytes() const { return impl_->bytes; }

const std::int32_t* Labeller::device_sites() const { return impl_->site; }

}  // namespace qtmv::label::cuda
