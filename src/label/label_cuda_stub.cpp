// The CUDA back end of a build without CUDA: no devices.
#include <stdexcept>

#include "label/label_cuda.hpp"

namespace qtmv::label::cuda {

int device_count() { return 0; }

void warm_up(int) {}

void release_cached_memory(int) {}

DeviceInfo device_info(int) { throw std::runtime_error("qtmvoronoi was built without CUDA"); }

struct Labeller::Impl {};

Labeller::Labeller(int, const std::vector<Piece>&, const Tree*, int) {
  throw std::runtime_error("qtmvoronoi was built without CUDA");
}
Labeller::Labeller(int, const std::vector<Piece>&, int, bool, int, const CoverView*) {
  throw std::runtime_error("qtmvoronoi was built without CUDA");
}
Labeller::Labeller(int, const LabelInput&, bool, int, const CoverView*) { throw std::runtime_error("qtmvoronoi was built without CUDA"); }
Labeller::~Labeller() = default;
TreeInfo Labeller::tree_info() const { return {}; }
void Labeller::download_tree(DefaultInitVector<TreeNode>*, DefaultInitVector<std::int32_t>*,
                             DefaultInitVector<JumpEntry>*) const {}
void Labeller::reserve(std::uint64_t, bool, bool) {}
float Labeller::run(grid::Code, std::uint64_t, bool, bool) { return 0; }
float Labeller::download(std::uint64_t, std::uint64_t, std::int32_t*, float*, std::uint8_t*) { return 0; }
float Labeller::select_outline(grid::Code, std::uint64_t, OutlineCells*, std::uint64_t) { return 0; }
std::size_t Labeller::device_bytes() const { return 0; }
std::vector<std::int32_t> Labeller::brute_sites(const std::vector<grid::Code>&) { return {}; }
const std::int32_t* Labeller::device_sites() const { return nullptr; }

}  // namespace qtmv::label::cuda
