#include "project.h"

#include "project_math.h"

namespace edgedog {

void project_forward(const PinholeCamera& cam, const ProjectInputs& in, const ProjectOutputs& out) {
#pragma omp parallel for schedule(static)
  for (int64_t i = 0; i < in.n; ++i) projection::forward_one(cam, in, out, i);
}

void project_backward(const PinholeCamera& cam, const ProjectInputs& in, const ProjectGradOutputs& go,
                      const ProjectGradInputs& gi) {
#pragma omp parallel for schedule(static)
  for (int64_t i = 0; i < in.n; ++i) projection::backward_one(cam, in, go, gi, i);
}

}  // namespace edgedog
