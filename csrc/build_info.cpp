#include "build_info.h"

#include "parallel.h"

namespace edgedog {

BuildInfo build_info() {
  BuildInfo info;
#ifdef _OPENMP
  info.openmp = true;
#else
  info.openmp = false;
#endif
  info.max_threads = max_threads();
#if defined(__clang__)
  info.compiler = std::string("clang ") + __clang_version__;
#elif defined(__GNUC__)
  info.compiler = std::string("gcc ") + __VERSION__;
#else
  info.compiler = "unknown";
#endif
  return info;
}

}  // namespace edgedog
