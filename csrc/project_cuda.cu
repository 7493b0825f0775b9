// CUDA kernels of the EWA projection: one thread per primitive, the CPU's maths (project_math.h).
#include "cuda_kernels.h"
#include "project_math.h"

namespace edgedog {
namespace cuda {
namespace {

constexpr int kThreads = 256;

int blocks_for(int64_t n) { return int((n + kThreads - 1) / kThreads); }

__global__ void project_forward_kernel(PinholeCamera cam, ProjectInputs in, ProjectOutputs out) {
  const int64_t i = int64_t(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < in.n) projection::forward_one(cam, in, out, i);
}

__global__ void project_backward_kernel(PinholeCamera cam, ProjectInputs in, ProjectGradOutputs go,
                                        ProjectGradInputs gi) {
  const int64_t i = int64_t(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < in.n) projection::backward_one(cam, in, go, gi, i);
}

}  // namespace

cudaError_t project_forward(const PinholeCamera& cam, const ProjectInputs& in, const ProjectOutputs& out,
                            cudaStream_t stream) {
  if (in.n == 0) return cudaSuccess;
  project_forward_kernel<<<blocks_for(in.n), kThreads, 0, stream>>>(cam, in, out);
  return cudaGetLastError();
}

cudaError_t project_backward(const PinholeCamera& cam, const ProjectInputs& in, const ProjectGradOutputs& go,
                             const ProjectGradInputs& gi, cudaStream_t stream) {
  if (in.n == 0) return cudaSuccess;
  project_backward_kernel<<<blocks_for(in.n), kThreads, 0, stream>>>(cam, in, go, gi);
  return cudaGetLastError();
}

}  // namespace cuda
}  // namespace edgedog
