// The one translation unit that includes torch/extension.h: it only binds the kernels
// declared in the plain-C++ headers of csrc/ to Python as `edgedog.renderer._C`.
#include <torch/extension.h>

#include "build_info.h"

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.doc() = "EdgeDoG CPU kernels";
  m.def(
      "build_info",
      []() {
        const edgedog::BuildInfo info = edgedog::build_info();
        pybind11::dict d;
        d["openmp"] = info.openmp;
        d["max_threads"] = info.max_threads;
        d["compiler"] = info.compiler;
        return d;
      },
      "Build facts: OpenMP on or off, its thread count, the compiler.");
}
