// EWA projection of 3D Gaussians into one pinhole camera, forward and backward.
// Plain C++ over contiguous float32 arrays; the maths in double (the 2x2 covariance of a thin,
// long primitive loses its determinant to cancellation in float32). Mirrors
// renderer/_torch_ref.py: project(), whose outputs include the support ellipse's extents.
#pragma once

#include <cstdint>

namespace edgedog {

struct PinholeCamera {
  double fx, fy, cx, cy;
  double R[9];  // world-to-camera rotation, row-major
  double t[3];  // world-to-camera translation
  int width, height;
  double near;
};

struct ProjectInputs {
  int64_t n;
  const float* means;      // (n, 3)
  const float* scales;     // (n, 3) positive
  const float* quats;      // (n, 4) w, x, y, z; any norm
  const float* support_q;  // (n,) Mahalanobis radius^2 of the footprint's support (0: none)
  double eps2d;            // screen-space dilation (px^2)
};

struct ProjectOutputs {
  float* means2d;  // (n, 2) pixels
  float* conics;   // (n, 3) inverse 2D covariance (a, b, c)
  float* depths;   // (n,) camera z, 0 when culled
  float* extents;  // (n, 2) half-widths of the support ellipse in pixels, 0 when culled
  uint8_t* valid;  // (n,) in front of the near plane
};

struct ProjectGradOutputs {  // gradients of the loss w.r.t. the forward outputs
  const float* means2d;
  const float* conics;
  const float* depths;
};

struct ProjectGradInputs {  // gradients written for the forward inputs
  float* means;
  float* scales;
  float* quats;
};

void project_forward(const PinholeCamera& cam, const ProjectInputs& in, const ProjectOutputs& out);
void project_backward(const PinholeCamera& cam, const ProjectInputs& in, const ProjectGradOutputs& grad_out,
                      const ProjectGradInputs& grad_in);

}  // namespace edgedog
