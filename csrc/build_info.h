// Build facts of the C++ extension, in plain C++ (no torch headers: only bindings.cpp
// includes torch/extension.h, which costs ~40 s and ~2 GB per translation unit).
#pragma once

#include <string>

namespace edgedog {

struct BuildInfo {
  bool openmp;           // compiled with OpenMP
  int max_threads;       // omp_get_max_threads() at call time (1 without OpenMP)
  std::string compiler;  // compiler name and version
};

BuildInfo build_info();

}  // namespace edgedog
