// One copy of the maths for both backends: the functions that the CPU kernels and the CUDA
// kernels share are marked EDGEDOG_HD, which is __host__ __device__ under nvcc and nothing for
// the host compiler.
#pragma once

#ifdef __CUDACC__
#define EDGEDOG_HD __host__ __device__
#else
#define EDGEDOG_HD
#endif
