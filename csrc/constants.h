// Constants shared by the kernels; mirrored in renderer/config.py (a test checks both agree).
#pragma once

namespace edgedog {

constexpr int kTileSize = 16;
constexpr float kAlphaMin = 1.0f / 255.0f;  // skip a primitive at a pixel below this alpha
constexpr float kAlphaMax = 0.99f;          // clamp alpha so T can be recovered backwards
constexpr float kEarlyStopT = 0.99e-4f;     // stop below this T; just under (1 - 0.99)^2, no tie
constexpr double kFrustumSlack = 1.3;       // EWA Jacobian clamp, in half fields of view

}  // namespace edgedog
