// The one translation unit that includes torch/extension.h. It registers the rasterizer's
// stages as ops of torch's dispatcher (library `edgedog`, schemas below), with these functions
// as their kernels on the CPU and, in a CUDA build (EDGEDOG_WITH_CUDA), on CUDA (and the
// training step's fused projection loss, `edge_loss`, on the CPU alone): each checks
// that its tensors share one device, allocates the outputs there and calls the plain-C++
// kernels of csrc/ or the CUDA launchers of cuda_kernels.h. renderer/ops.py calls the ops and
// owns their autograd (edgedog/train/losses.py the loss's). The Python module
// `edgedog.renderer._C` itself only reports build facts and sets the allocator up.
#include <torch/extension.h>

#include <malloc.h>

#include <limits>
#include <optional>
#include <string>
#include <tuple>

#include "build_info.h"
#include "constants.h"
#include "edge_loss.h"
#include "project.h"
#include "rasterize.h"
#include "tiles.h"

#ifdef EDGEDOG_WITH_CUDA
#include <c10/cuda/CUDAGuard.h>
#include <c10/cuda/CUDAStream.h>

#include "cuda_kernels.h"

// Runs `launch` (an expression of `stream`, returning a cudaError_t) on the device of the
// tensor `like`, on torch's current stream.
#define EDGEDOG_CUDA_LAUNCH(like, launch)                                                  \
  do {                                                                                     \
    const c10::cuda::CUDAGuard guard((like).device());                                     \
    const cudaStream_t stream = c10::cuda::getCurrentCUDAStream();                         \
    const cudaError_t error = (launch);                                                    \
    TORCH_CHECK(error == cudaSuccess, "edgedog CUDA kernel: ", cudaGetErrorString(error)); \
  } while (0)
#else
#define EDGEDOG_CUDA_LAUNCH(like, launch) TORCH_CHECK(false, "edgedog was built without CUDA")
#endif

namespace {

using torch::Tensor;

void check_device(const Tensor& t, const char* name, const torch::Device& device) {
  TORCH_CHECK(t.device() == device, name, " is on ", t.device(), ", the other inputs on ", device);
}

void check_float(const Tensor& t, const char* name, std::vector<int64_t> shape, const torch::Device& device) {
  check_device(t, name, device);
  TORCH_CHECK(t.scalar_type() == torch::kFloat32, name, " must be float32, got ", t.scalar_type());
  TORCH_CHECK(t.is_contiguous(), name, " must be contiguous");
  TORCH_CHECK(t.dim() == int64_t(shape.size()), name, " must have ", shape.size(), " dimensions");
  for (size_t k = 0; k < shape.size(); ++k) {
    TORCH_CHECK(shape[k] < 0 || t.size(k) == shape[k], name, " has size ", t.size(k), " in dimension ", k,
                ", expected ", shape[k]);
  }
}

edgedog::PinholeCamera camera_from(const Tensor& K, const Tensor& w2c, int64_t width, int64_t height,
                                   double near) {
  TORCH_CHECK(K.sizes() == torch::IntArrayRef({3, 3}), "K must be 3x3");
  TORCH_CHECK(w2c.sizes() == torch::IntArrayRef({4, 4}), "w2c must be 4x4");
  TORCH_CHECK(width > 0 && height > 0, "image size must be positive");
  // Read on the host (renderer/ops.py keeps cameras there: no copy back from a device).
  const auto k = K.to(torch::kCPU, torch::kFloat64).contiguous();
  const auto m = w2c.to(torch::kCPU, torch::kFloat64).contiguous();
  const double* kp = k.data_ptr<double>();
  const double* mp = m.data_ptr<double>();
  edgedog::PinholeCamera cam{};
  cam.fx = kp[0];
  cam.fy = kp[4];
  cam.cx = kp[2];
  cam.cy = kp[5];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) cam.R[3 * r + c] = mp[4 * r + c];
    cam.t[r] = mp[4 * r + 3];
  }
  cam.width = int(width);
  cam.height = int(height);
  cam.near = near;
  return cam;
}

edgedog::ProjectInputs project_inputs(const Tensor& means, const Tensor& scales, const Tensor& quats,
                                      const Tensor& support_q, double eps2d) {
  const int64_t n = means.size(0);
  const auto device = means.device();
  check_float(means, "means", {n, 3}, device);
  check_float(scales, "scales", {n, 3}, device);
  check_float(quats, "quats", {n, 4}, device);
  check_float(support_q, "support_q", {n}, device);
  return {n,
          means.data_ptr<float>(),
          scales.data_ptr<float>(),
          quats.data_ptr<float>(),
          support_q.data_ptr<float>(),
          eps2d};
}

using Tensors3 = std::tuple<Tensor, Tensor, Tensor>;
using Tensors5 = std::tuple<Tensor, Tensor, Tensor, Tensor, Tensor>;

Tensors5 project_forward(const Tensor& means, const Tensor& scales, const Tensor& quats,
                         const Tensor& support_q, const Tensor& K, const Tensor& w2c, int64_t width,
                         int64_t height, double near, double eps2d) {
  const auto in = project_inputs(means, scales, quats, support_q, eps2d);
  const auto cam = camera_from(K, w2c, width, height, near);
  auto f = means.options();
  Tensor means2d = torch::empty({in.n, 2}, f), conics = torch::empty({in.n, 3}, f);
  Tensor depths = torch::empty({in.n}, f), extents = torch::empty({in.n, 2}, f);
  Tensor valid = torch::empty({in.n}, f.dtype(torch::kBool));
  const edgedog::ProjectOutputs out{means2d.data_ptr<float>(), conics.data_ptr<float>(),
                                    depths.data_ptr<float>(), extents.data_ptr<float>(),
                                    reinterpret_cast<uint8_t*>(valid.data_ptr<bool>())};
  if (means.is_cuda()) {
    EDGEDOG_CUDA_LAUNCH(means, edgedog::cuda::project_forward(cam, in, out, stream));
  } else {
    edgedog::project_forward(cam, in, out);
  }
  return {means2d, conics, depths, extents, valid};
}

Tensors3 project_backward(const Tensor& means, const Tensor& scales, const Tensor& quats,
                          const Tensor& support_q, const Tensor& K, const Tensor& w2c, int64_t width,
                          int64_t height, double near, double eps2d, const Tensor& g_means2d,
                          const Tensor& g_conics, const Tensor& g_depths) {
  const auto in = project_inputs(means, scales, quats, support_q, eps2d);
  const auto cam = camera_from(K, w2c, width, height, near);
  check_float(g_means2d, "grad means2d", {in.n, 2}, means.device());
  check_float(g_conics, "grad conics", {in.n, 3}, means.device());
  check_float(g_depths, "grad depths", {in.n}, means.device());
  Tensor g_means = torch::empty_like(means), g_scales = torch::empty_like(scales);
  Tensor g_quats = torch::empty_like(quats);
  const edgedog::ProjectGradOutputs go{g_means2d.data_ptr<float>(), g_conics.data_ptr<float>(),
                                       g_depths.data_ptr<float>()};
  const edgedog::ProjectGradInputs gi{g_means.data_ptr<float>(), g_scales.data_ptr<float>(),
                                      g_quats.data_ptr<float>()};
  if (means.is_cuda()) {
    EDGEDOG_CUDA_LAUNCH(means, edgedog::cuda::project_backward(cam, in, go, gi, stream));
  } else {
    edgedog::project_backward(cam, in, go, gi);
  }
  return {g_means, g_scales, g_quats};
}

#ifdef EDGEDOG_WITH_CUDA
// The lists on the device: each primitive's (tile, depth) keys, sorted stably by torch (so the
// index breaks depth ties, as on the CPU), and each tile's first entry found by binary search.
// The lists' length is read back to the host once, to allocate them.
std::tuple<Tensor, Tensor> tile_lists_cuda(const Tensor& means2d, const Tensor& depths, const Tensor& extents,
                                           const Tensor& valid, int64_t width, int64_t height) {
  const int64_t n = means2d.size(0);
  const int64_t tiles = ((width + edgedog::kTileSize - 1) / edgedog::kTileSize) *
                        ((height + edgedog::kTileSize - 1) / edgedog::kTileSize);
  const auto i64 = means2d.options().dtype(torch::kInt64);
  const auto* mask = reinterpret_cast<const uint8_t*>(valid.data_ptr<bool>());
  Tensor counts = torch::empty({n}, i64);
  EDGEDOG_CUDA_LAUNCH(
      means2d, edgedog::cuda::tile_counts(n, means2d.data_ptr<float>(), extents.data_ptr<float>(), mask,
                                          int(width), int(height), counts.data_ptr<int64_t>(), stream));
  const Tensor ends = counts.cumsum(0);
  const int64_t total = n == 0 ? 0 : ends[n - 1].item<int64_t>();
  TORCH_CHECK(total <= std::numeric_limits<int32_t>::max(), "the tile lists would hold ", total,
              " entries, more than int32 offsets can index");
  Tensor keys = torch::empty({total}, i64);
  Tensor values = torch::empty({total}, means2d.options().dtype(torch::kInt32));
  EDGEDOG_CUDA_LAUNCH(means2d,
                      edgedog::cuda::tile_keys(n, means2d.data_ptr<float>(), depths.data_ptr<float>(),
                                               extents.data_ptr<float>(), mask, int(width), int(height),
                                               ends.data_ptr<int64_t>(), keys.data_ptr<int64_t>(),
                                               values.data_ptr<int32_t>(), stream));
  const auto [sorted, order] = keys.sort(/*stable=*/true, /*dim=*/0, /*descending=*/false);
  const Tensor tile_of = torch::bitwise_right_shift(sorted, 32);
  const Tensor offsets = torch::searchsorted(tile_of, torch::arange(tiles + 1, i64), /*out_int32=*/true);
  return {offsets, values.index_select(0, order)};
}
#endif

std::tuple<Tensor, Tensor> tile_lists(const Tensor& means2d, const Tensor& depths, const Tensor& extents,
                                      const Tensor& valid, int64_t width, int64_t height) {
  const int64_t n = means2d.size(0);
  const auto device = means2d.device();
  check_float(means2d, "means2d", {n, 2}, device);
  check_float(depths, "depths", {n}, device);
  check_float(extents, "extents", {n, 2}, device);
  check_device(valid, "valid", device);
  TORCH_CHECK(valid.scalar_type() == torch::kBool && valid.is_contiguous() && valid.numel() == n,
              "valid must be a contiguous bool tensor of n entries");
  TORCH_CHECK(width > 0 && height > 0, "image size must be positive");
#ifdef EDGEDOG_WITH_CUDA
  if (means2d.is_cuda()) return tile_lists_cuda(means2d, depths, extents, valid, width, height);
#endif
  const auto lists = edgedog::build_tile_lists(
      n, means2d.data_ptr<float>(), depths.data_ptr<float>(), extents.data_ptr<float>(),
      reinterpret_cast<const uint8_t*>(valid.data_ptr<bool>()), int(width), int(height));
  auto i32 = means2d.options().dtype(torch::kInt32);
  Tensor offsets = torch::empty({int64_t(lists.offsets.size())}, i32);
  Tensor ids = torch::empty({int64_t(lists.ids.size())}, i32);
  std::copy(lists.offsets.begin(), lists.offsets.end(), offsets.data_ptr<int32_t>());
  std::copy(lists.ids.begin(), lists.ids.end(), ids.data_ptr<int32_t>());
  return {offsets, ids};
}

struct SplatArgs {
  edgedog::Splats splats;
  edgedog::Frame frame;
  edgedog::TileView tiles;
};

// The 14 arguments that every compositing op starts with, checked.
SplatArgs splat_args(const Tensor& means2d, const Tensor& conics, const Tensor& depths, const Tensor& extents,
                     const Tensor& opacity, const Tensor& a, const Tensor& t, const Tensor& support,
                     const Tensor& colors, const Tensor& offsets, const Tensor& ids, int64_t width,
                     int64_t height, const std::optional<Tensor>& background) {
  const int64_t n = means2d.size(0);
  const auto device = means2d.device();
  check_float(means2d, "means2d", {n, 2}, device);
  check_float(conics, "conics", {n, 3}, device);
  check_float(depths, "depths", {n}, device);
  check_float(extents, "extents", {n, 2}, device);
  check_float(opacity, "opacity", {n}, device);
  check_float(a, "a", {n}, device);
  check_float(t, "t", {n}, device);
  check_float(support, "support", {n}, device);
  check_float(colors, "colors", {n, -1}, device);
  const int64_t C = colors.size(1);
  TORCH_CHECK(C >= 1, "colors need at least one channel");
#ifdef EDGEDOG_WITH_CUDA
  TORCH_CHECK(!device.is_cuda() || C <= edgedog::cuda::kMaxChannels, "the CUDA kernels take at most ",
              edgedog::cuda::kMaxChannels, " colour channels, got ", C);
#endif
  check_device(offsets, "tile offsets", device);
  check_device(ids, "tile ids", device);
  const int tiles_x = int((width + edgedog::kTileSize - 1) / edgedog::kTileSize);
  const int tiles_y = int((height + edgedog::kTileSize - 1) / edgedog::kTileSize);
  TORCH_CHECK(offsets.scalar_type() == torch::kInt32 && offsets.is_contiguous() &&
                  offsets.numel() == int64_t(tiles_x) * tiles_y + 1,
              "tile offsets do not match the image size");
  TORCH_CHECK(ids.scalar_type() == torch::kInt32 && ids.is_contiguous(), "tile ids must be int32");
  const float* bg = nullptr;
  if (background.has_value()) {
    check_float(*background, "background", {C}, device);
    bg = background->data_ptr<float>();
  }
  return {{n, int(C), means2d.data_ptr<float>(), conics.data_ptr<float>(), depths.data_ptr<float>(),
           extents.data_ptr<float>(), opacity.data_ptr<float>(), a.data_ptr<float>(), t.data_ptr<float>(),
           support.data_ptr<float>(), colors.data_ptr<float>()},
          {int(width), int(height), bg},
          {tiles_x, tiles_y, offsets.data_ptr<int32_t>(), ids.data_ptr<int32_t>()}};
}

Tensors5 rasterize_forward(const Tensor& means2d, const Tensor& conics, const Tensor& depths,
                           const Tensor& extents, const Tensor& opacity, const Tensor& a, const Tensor& t,
                           const Tensor& support, const Tensor& colors, const Tensor& offsets,
                           const Tensor& ids, int64_t width, int64_t height,
                           const std::optional<Tensor>& background) {
  const auto args = splat_args(means2d, conics, depths, extents, opacity, a, t, support, colors, offsets, ids,
                               width, height, background);
  auto f = means2d.options();
  Tensor image = torch::empty({height, width, colors.size(1)}, f);
  Tensor alpha = torch::empty({height, width}, f), depth = torch::empty({height, width}, f);
  Tensor final_T = torch::empty({height, width}, f);
  Tensor last = torch::empty({height, width}, f.dtype(torch::kInt32));
  const edgedog::RasterOutputs out{image.data_ptr<float>(), alpha.data_ptr<float>(), depth.data_ptr<float>(),
                                   final_T.data_ptr<float>(), last.data_ptr<int32_t>()};
  if (means2d.is_cuda()) {
    EDGEDOG_CUDA_LAUNCH(means2d,
                        edgedog::cuda::rasterize_forward(args.splats, args.frame, args.tiles, out, stream));
  } else {
    edgedog::rasterize_forward(args.splats, args.frame, args.tiles, out);
  }
  return {image, alpha, depth, final_T, last};
}

void check_state(const Tensor& final_T, const Tensor& last, int64_t width, int64_t height) {
  check_float(final_T, "final_T", {height, width}, last.device());
  TORCH_CHECK(last.scalar_type() == torch::kInt32 && last.is_contiguous() && last.numel() == width * height,
              "last must be a contiguous int32 (H, W) tensor");
}

std::tuple<Tensor, Tensor, Tensor, Tensor, Tensor, Tensor, Tensor, Tensor> rasterize_backward(
    const Tensor& means2d, const Tensor& conics, const Tensor& depths, const Tensor& extents,
    const Tensor& opacity, const Tensor& a, const Tensor& t, const Tensor& support, const Tensor& colors,
    const Tensor& offsets, const Tensor& ids, int64_t width, int64_t height,
    const std::optional<Tensor>& background, const Tensor& final_T, const Tensor& last, const Tensor& g_image,
    const Tensor& g_alpha, const Tensor& g_depth) {
  const auto args = splat_args(means2d, conics, depths, extents, opacity, a, t, support, colors, offsets, ids,
                               width, height, background);
  const auto device = means2d.device();
  check_device(last, "last", device);
  check_state(final_T, last, width, height);
  check_float(g_image, "grad image", {height, width, colors.size(1)}, device);
  check_float(g_alpha, "grad alpha", {height, width}, device);
  check_float(g_depth, "grad depth", {height, width}, device);
  // The CUDA kernels add into their outputs; the CPU's write every entry.
  const auto make = [&](const Tensor& like) {
    return means2d.is_cuda() ? torch::zeros_like(like) : torch::empty_like(like);
  };
  Tensor gm = make(means2d), gc = make(conics), gd = make(depths), go = make(opacity), ga = make(a),
         gt = make(t);
  Tensor gcol = make(colors), absgrad = make(means2d);
  const edgedog::RasterGradOutputs grad_out{g_image.data_ptr<float>(), g_alpha.data_ptr<float>(),
                                            g_depth.data_ptr<float>()};
  const edgedog::SplatGrads grads{gm.data_ptr<float>(),   gc.data_ptr<float>(),     gd.data_ptr<float>(),
                                  go.data_ptr<float>(),   ga.data_ptr<float>(),     gt.data_ptr<float>(),
                                  gcol.data_ptr<float>(), absgrad.data_ptr<float>()};
  const float* final_T_ptr = final_T.data_ptr<float>();
  const int32_t* last_ptr = last.data_ptr<int32_t>();
  if (means2d.is_cuda()) {
    EDGEDOG_CUDA_LAUNCH(
        means2d, edgedog::cuda::rasterize_backward(args.splats, args.frame, args.tiles, final_T_ptr, last_ptr,
                                                   grad_out, grads, stream));
  } else {
    edgedog::rasterize_backward(args.splats, args.frame, args.tiles, final_T_ptr, last_ptr, grad_out, grads);
  }
  return {gm, gc, gd, go, ga, gt, gcol, absgrad};
}

Tensor rasterize_fisher(const Tensor& means2d, const Tensor& conics, const Tensor& depths,
                        const Tensor& extents, const Tensor& opacity, const Tensor& a, const Tensor& t,
                        const Tensor& support, const Tensor& colors, const Tensor& offsets, const Tensor& ids,
                        int64_t width, int64_t height, const std::optional<Tensor>& background,
                        const Tensor& final_T, const Tensor& last) {
  const auto args = splat_args(means2d, conics, depths, extents, opacity, a, t, support, colors, offsets, ids,
                               width, height, background);
  check_device(last, "last", means2d.device());
  check_state(final_T, last, width, height);
  Tensor fisher = torch::zeros({means2d.size(0)}, means2d.options());
  const float* final_T_ptr = final_T.data_ptr<float>();
  const int32_t* last_ptr = last.data_ptr<int32_t>();
  if (means2d.is_cuda()) {
    EDGEDOG_CUDA_LAUNCH(
        means2d, edgedog::cuda::rasterize_fisher(args.splats, args.frame, args.tiles, final_T_ptr, last_ptr,
                                                 fisher.data_ptr<float>(), stream));
  } else {
    edgedog::rasterize_fisher(args.splats, args.frame, args.tiles, final_T_ptr, last_ptr,
                              fisher.data_ptr<float>());
  }
  return fisher;
}

std::tuple<Tensor, Tensor> edge_loss(const Tensor& render, const Tensor& target,
                                     const std::optional<Tensor>& depth, int64_t weighting,
                                     const std::optional<Tensor>& sample) {
  const auto device = render.device();
  TORCH_CHECK(device.is_cpu(), "edge_loss has a CPU kernel only (other devices: losses.py's torch path)");
  check_float(render, "render", {-1, -1}, device);
  const int64_t height = render.size(0), width = render.size(1);
  check_float(target, "target", {height, width}, device);
  TORCH_CHECK(weighting >= 0 && weighting <= int64_t(edgedog::Weighting::kExp), "unknown weighting ",
              weighting);
  Tensor weight;
  if (depth.has_value()) {
    check_float(*depth, "depth", {height, width}, device);
    weight = torch::empty_like(render);
    edgedog::uncertainty_weight(depth->data_ptr<float>(), height, width, edgedog::Weighting(weighting),
                                weight.data_ptr<float>());
  }
  const int64_t* sample_ptr = nullptr;
  int64_t sample_count = 0;
  if (sample.has_value()) {
    check_device(*sample, "sample", device);
    TORCH_CHECK(sample->scalar_type() == torch::kInt64 && sample->dim() == 1 && sample->is_contiguous(),
                "sample must be a contiguous 1-D int64 tensor");
    sample_count = sample->size(0);
    sample_ptr = sample->data_ptr<int64_t>();
    if (sample_count > 0) {
      const auto [lo, hi] = torch::aminmax(*sample);
      TORCH_CHECK(lo.item<int64_t>() >= 0 && hi.item<int64_t>() < height * width,
                  "sample index out of range");
    }
  }
  Tensor grad = torch::empty_like(render);
  const double loss = edgedog::weighted_l1(render.data_ptr<float>(), target.data_ptr<float>(),
                                           weight.defined() ? weight.data_ptr<float>() : nullptr,
                                           height * width, sample_ptr, sample_count, grad.data_ptr<float>());
  return {torch::scalar_tensor(loss, render.options()), grad};
}

}  // namespace

// The schemas: one argument order for every device's kernels and for the Python wrappers.
// Per-primitive tensors come in the order the projection returns them (means2d, conics, depths,
// extents, valid), then the activated parameters (opacity, a, t, support) and the colours.
#define EDGEDOG_SPLATS                                                                                 \
  "Tensor means2d, Tensor conics, Tensor depths, Tensor extents, Tensor opacity, Tensor a, Tensor t, " \
  "Tensor support, Tensor colors, Tensor offsets, Tensor ids, int width, int height, Tensor? background"
#define EDGEDOG_PROJECT                                                                            \
  "Tensor means, Tensor scales, Tensor quats, Tensor support_q, Tensor K, Tensor w2c, int width, " \
  "int height, float near, float eps2d"

TORCH_LIBRARY(edgedog, m) {
  m.def("project_forward(" EDGEDOG_PROJECT
        ") -> (Tensor means2d, Tensor conics, Tensor depths, Tensor extents, Tensor valid)");
  m.def("project_backward(" EDGEDOG_PROJECT
        ", Tensor g_means2d, Tensor g_conics, Tensor g_depths) -> (Tensor g_means, Tensor g_scales, "
        "Tensor g_quats)");
  m.def(
      "tile_lists(Tensor means2d, Tensor depths, Tensor extents, Tensor valid, int width, int height)"
      " -> (Tensor offsets, Tensor ids)");
  m.def("rasterize_forward(" EDGEDOG_SPLATS
        ") -> (Tensor image, Tensor alpha, Tensor depth, Tensor final_T, Tensor last)");
  m.def(
      "rasterize_backward(" EDGEDOG_SPLATS
      ", Tensor final_T, Tensor last, Tensor g_image, Tensor g_alpha, Tensor g_depth) -> (Tensor g_means2d, "
      "Tensor g_conics, Tensor g_depths, Tensor g_opacity, Tensor g_a, Tensor g_t, Tensor g_colors, "
      "Tensor absgrad)");
  m.def("rasterize_fisher(" EDGEDOG_SPLATS ", Tensor final_T, Tensor last) -> Tensor fisher");
  m.def(
      "edge_loss(Tensor render, Tensor target, Tensor? depth, int weighting, Tensor? sample)"
      " -> (Tensor loss, Tensor grad_render)");
}

#undef EDGEDOG_SPLATS
#undef EDGEDOG_PROJECT

// The same functions serve every device: each dispatches on its first tensor's.
#define EDGEDOG_IMPLS(m)                             \
  m.impl("project_forward", &project_forward);       \
  m.impl("project_backward", &project_backward);     \
  m.impl("tile_lists", &tile_lists);                 \
  m.impl("rasterize_forward", &rasterize_forward);   \
  m.impl("rasterize_backward", &rasterize_backward); \
  m.impl("rasterize_fisher", &rasterize_fisher)

TORCH_LIBRARY_IMPL(edgedog, CPU, m) {
  EDGEDOG_IMPLS(m);
  m.impl("edge_loss", &edge_loss);  // the CPU's only: a GPU runs the loss as torch ops
}

#ifdef EDGEDOG_WITH_CUDA
TORCH_LIBRARY_IMPL(edgedog, CUDA, m) { EDGEDOG_IMPLS(m); }
#endif

#undef EDGEDOG_IMPLS

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.doc() =
      "EdgeDoG kernels (CPU, and CUDA in a CUDA build): the ops are torch.ops.edgedog.*, registered on "
      "import";
  m.def(
      "tune_allocator",
      []() {
        // Every render allocates a few image-sized tensors. glibc serves blocks above its mmap
        // threshold with fresh pages, and page faults on them cost as much as the rendering
        // itself: keep such blocks on the heap, where they are reused from one step to the next.
        mallopt(M_MMAP_THRESHOLD, 256 << 20);
        mallopt(M_TRIM_THRESHOLD, 512 << 20);
      },
      "Keep blocks up to 256 MiB on glibc's heap (process-wide; called by load_extension).");
  m.def(
      "build_info",
      []() {
        const edgedog::BuildInfo info = edgedog::build_info();
        pybind11::dict d;
        d["openmp"] = info.openmp;
        d["max_threads"] = info.max_threads;
        d["compiler"] = info.compiler;
#ifdef EDGEDOG_WITH_CUDA
        d["cuda"] = true;
#else
        d["cuda"] = false;
#endif
        return d;
      },
      "Build facts: OpenMP on or off, its thread count, the compiler, whether the CUDA kernels are in.");
  m.def(
      "constants",
      []() {
        pybind11::dict d;
        d["tile_size"] = edgedog::kTileSize;
        d["alpha_min"] = edgedog::kAlphaMin;
        d["alpha_max"] = edgedog::kAlphaMax;
        d["early_stop_t"] = edgedog::kEarlyStopT;
        d["frustum_slack"] = edgedog::kFrustumSlack;
        return d;
      },
      "The kernels' constants, to check them against renderer/config.py.");
}
