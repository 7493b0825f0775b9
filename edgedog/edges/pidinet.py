"""PiDiNet (Su et al., "Pixel Difference Networks for Efficient Edge Detection", ICCV 2021) in
plain torch, loading the official checkpoints of github.com/hellozhuo/pidinet.

The official network is configuration ``carv4`` with CDCM and CSAM (``--dil --sa``). Its 16
pixel-difference convolutions (PDCs) compute sums of weighted pixel *differences*; each is a
linear function of the input, so it equals a plain convolution with a rearranged kernel. We
rearrange the kernels once, at load time (`convert_pdc`), and inference runs only standard
``nn.Conv2d`` layers.

Layout (C = 60 / 30 / 20 for the full / -small / -tiny checkpoints, D = the CDCM width,
24 / 12 / 8)::

    image (N, 3, H, W), normalised
    init_block       3x3 PDC 3 -> C                               (N, C, H, W)
    stage 1          blocks 1_1..1_3, C                           (N, C, H, W)
    stage 2          blocks 2_1..2_4, 2C, 2_1 max-pools by 2      (N, 2C, H/2, W/2)
    stage 3          blocks 3_1..3_4, 4C, 3_1 max-pools by 2      (N, 4C, H/4, W/4)
    stage 4          blocks 4_1..4_4, 4C, 4_1 max-pools by 2      (N, 4C, H/8, W/8)
    per stage s      CDCM -> CSAM -> 1x1 conv to 1 -> bilinear to (H, W): side map s
    classifier       1x1 conv over the 4 side maps: the fused map
    outputs          sigmoid of side 1..4 and of the fused map    (N, 5, H, W)
"""

from __future__ import annotations

import hashlib
import importlib.resources
import os
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from edgedog.edges.detector import EdgeDetector
from edgedog.errors import InputError

WEIGHTS_ENV = "EDGEDOG_PIDINET"

# The official file of each training set (BSDS500, NYUD, Multicue: tables 5, 6, 7 of the paper).
PIDINET_FILES = {
    "bsds": "table5_pidinet.pth",
    "bsds-small": "table5_pidinet-small.pth",
    "bsds-tiny": "table5_pidinet-tiny.pth",
    "nyud": "table6_pidinet.pth",
    "multicue": "table7_pidinet.pth",
}

SHIPPED_VARIANT = "bsds"
SHIPPED_SHA256 = "80860ac267258b5f27486e0ef152a211d0b08120f62aeb185a050acc30da486c"
SHIPPED_WEIGHTS = Path(str(importlib.resources.files("edgedog.edges") / "weights"
                           / PIDINET_FILES[SHIPPED_VARIANT]))
"""The official table5_pidinet.pth ships with edgedog (package data, its MIT licence beside it):
the weights of 'pidinet' and 'auto' when none are given. Checked by SHIPPED_SHA256 before torch
reads it, so a damaged or replaced file is refused, never unpickled."""

WEIGHTS_MISSING = (
    "PiDiNet weights not found (edgedog ships only the BSDS ones); the official weights are "
    "published at https://github.com/hellozhuo/pidinet (trained_models/table5_pidinet.pth, ...): "
    "pass --weights PATH or set EDGEDOG_PIDINET"
)

OUTPUTS = ("side1", "side2", "side3", "side4", "fused")  # channel order of PiDiNet.forward

# Normalisation the official models were trained with (ImageNet statistics).
MEAN = (0.485, 0.456, 0.406)
STD = (0.229, 0.224, 0.225)

# carv4: PDC type of layer i is CARV4[i % 4]; layer 0 is init_block, layers 1..15 are the
# depthwise convs of blocks 1_1, 1_2, 1_3, 2_1, ..., 4_4 in that order.
CARV4 = ("cd", "ad", "rd", "cv")
STAGE_BLOCKS = (3, 4, 4, 4)
STAGE_WIDTHS = (1, 2, 4, 4)  # times C
CDCM_DILATIONS = (5, 7, 9, 11)

# ad: kernel position i of the 3x3 kernel (raster order) also weighs, negatively, the pixel
# whose weight is at _AD_SOURCE[i], the next pixel clockwise around the ring (centre: itself).
_AD_SOURCE = [3, 0, 1, 6, 4, 2, 7, 8, 5]
# rd: the 8 directions in raster order; the far pixel (distance 2) and the near one (distance 1)
# of each direction as flat indices of a 5x5 kernel.
_RD_FAR = [0, 2, 4, 10, 14, 20, 22, 24]
_RD_NEAR = [6, 7, 8, 11, 13, 16, 17, 18]


def convert_pdc(kind: str, weight: torch.Tensor) -> torch.Tensor:
    """The plain-convolution kernel equal to a pixel-difference convolution.

    Args:
        kind: "cd" (central), "ad" (angular), "rd" (radial) or "cv" (vanilla).
        weight: (O, I, 3, 3) trained PDC kernel.

    Returns:
        (O, I, 3, 3) kernel for "cd", "ad", "cv" (use padding 1); (O, I, 5, 5) for "rd"
        (use padding 2). The result is a new tensor.

    - cd: sum_i w_i (x_i - x_centre) = conv(x, w) - (sum_i w_i) x_centre, so the kernel's sum
      is subtracted at the centre.
    - ad: sum_i w_i (x_i - x_next(i)) around the ring; gathered per pixel, W - W[perm].
    - rd: sum_k w_k (x_far(k) - x_near(k)) along 8 directions, with the official choice of
      w_k = W.flat[k + 1] (raster order; W.flat[0] is unused): a 5x5 kernel with +w on the
      outer ring and -w on the inner ring.
    """
    out_ch, in_ch = weight.shape[:2]
    flat = weight.detach().reshape(out_ch, in_ch, 9)
    if kind == "cv":
        return flat.clone().reshape(weight.shape)
    if kind == "cd":
        kernel = flat.clone()
        kernel[:, :, 4] -= flat.sum(dim=2)
        return kernel.reshape(weight.shape)
    if kind == "ad":
        return (flat - flat[:, :, _AD_SOURCE]).reshape(weight.shape)
    if kind == "rd":
        kernel = flat.new_zeros(out_ch, in_ch, 25)
        kernel[:, :, _RD_FAR] = flat[:, :, 1:]
        kernel[:, :, _RD_NEAR] = -flat[:, :, 1:]
        return kernel.reshape(out_ch, in_ch, 5, 5)
    raise ValueError(f"unknown PDC type {kind!r}")


def _pdc_layer(kind: str, in_ch: int, out_ch: int, groups: int) -> nn.Conv2d:
    """The plain conv a PDC of `kind` becomes: 5x5 with padding 2 for "rd", else 3x3 padding 1."""
    size = 5 if kind == "rd" else 3
    return nn.Conv2d(in_ch, out_ch, size, padding=size // 2, groups=groups, bias=False)


class _Block(nn.Module):
    """Residual block: depthwise PDC -> ReLU -> 1x1 conv, plus the input.

    (N, I, H, W) -> (N, O, H, W), or (N, O, H/2, W/2) when `downsample`: then the input is
    first max-pooled 2x2 and the residual goes through a 1x1 conv (with bias) to O channels.
    """

    def __init__(self, kind: str, in_ch: int, out_ch: int, downsample: bool):
        super().__init__()
        self.downsample = downsample
        self.conv1 = _pdc_layer(kind, in_ch, in_ch, groups=in_ch)
        self.conv2 = nn.Conv2d(in_ch, out_ch, 1, bias=False)
        self.shortcut = nn.Conv2d(in_ch, out_ch, 1) if downsample else None

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.downsample:
            x = F.max_pool2d(x, 2)
        # In place where the tensor is this block's own: each full-resolution tensor is ~150 MB
        # at 800 x 800, and every allocation of that size costs its page faults.
        y = self.conv2(F.relu(self.conv1(x), inplace=True))
        return y.add_(self.shortcut(x) if self.downsample else x)


class _CDCM(nn.Module):
    """Compact dilation convolution module: ReLU, 1x1 conv to D channels, then the sum of four
    3x3 convs with dilations 5, 7, 9, 11 (a wide receptive field at little cost).
    (N, I, h, w) -> (N, D, h, w)."""

    def __init__(self, in_ch: int, dil: int):
        super().__init__()
        self.conv1 = nn.Conv2d(in_ch, dil, 1)
        for i, d in enumerate(CDCM_DILATIONS, start=1):
            self.add_module(f"conv2_{i}", nn.Conv2d(dil, dil, 3, padding=d, dilation=d, bias=False))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = self.conv1(F.relu(x))
        y = self.conv2_1(x)
        y += self.conv2_2(x)
        y += self.conv2_3(x)
        y += self.conv2_4(x)
        return y


class _CSAM(nn.Module):
    """Compact spatial attention: a (N, 1, h, w) mask from ReLU -> 1x1 conv to 4 -> 3x3 conv
    to 1 -> sigmoid scales the (N, D, h, w) input."""

    def __init__(self, channels: int):
        super().__init__()
        self.conv1 = nn.Conv2d(channels, 4, 1)
        self.conv2 = nn.Conv2d(4, 1, 3, padding=1, bias=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x * torch.sigmoid(self.conv2(self.conv1(F.relu(x))))


class PiDiNet(nn.Module):
    """PiDiNet carv4 + CDCM + CSAM, with its PDCs already converted to plain convolutions.

    Module names follow the official checkpoints (``init_block``, ``block1_1`` .. ``block4_4``,
    ``dilations``, ``attentions``, ``conv_reduces``, ``classifier``) so converted state_dicts
    load directly; build one with `load_pidinet`.

    Args:
        channels: C, the width of stage 1 (60, 30 or 20 in the official checkpoints).
        dil: D, the CDCM width (24, 12 or 8).
    """

    def __init__(self, channels: int, dil: int):
        super().__init__()
        self.channels, self.dil = channels, dil
        self.init_block = _pdc_layer(CARV4[0], 3, channels, groups=1)
        layer, in_ch, stages = 1, channels, []
        for stage, (n_blocks, width) in enumerate(zip(STAGE_BLOCKS, STAGE_WIDTHS), start=1):
            blocks = []
            for b in range(1, n_blocks + 1):
                # Stages 2..4 halve the resolution in their first block.
                downsample = stage > 1 and b == 1
                blocks.append(_Block(CARV4[layer % 4], in_ch, width * channels, downsample))
                self.add_module(f"block{stage}_{b}", blocks[-1])
                layer, in_ch = layer + 1, width * channels
            stages.append(nn.Sequential(*blocks))
        # Not registered (a plain tuple): the blocks are registered under their official names.
        self._stages = tuple(stages)
        widths = [w * channels for w in STAGE_WIDTHS]
        self.dilations = nn.ModuleList(_CDCM(w, dil) for w in widths)
        self.attentions = nn.ModuleList(_CSAM(dil) for _ in widths)
        self.conv_reduces = nn.ModuleList(nn.Conv2d(dil, 1, 1) for _ in widths)
        self.classifier = nn.Conv2d(4, 1, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(N, 3, H, W) normalised RGB -> (N, 5, H, W) probabilities: side 1..4, then fused."""
        size = x.shape[-2:]
        x = self.init_block(x)
        sides = []
        for i in range(4):
            x = self._stages[i](x)
            side = self.conv_reduces[i](self.attentions[i](self.dilations[i](x)))
            sides.append(F.interpolate(side, size, mode="bilinear", align_corners=False))
        logits = torch.cat(sides, dim=1)  # (N, 4, H, W)
        return torch.sigmoid(torch.cat([logits, self.classifier(logits)], dim=1))


def _convert_state_dict(official: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """Official (PDC) state_dict, ``module.`` prefix already stripped -> ours: PDC kernels
    converted, ``conv_reduces.i.conv.*`` -> ``conv_reduces.i.*``."""
    pdc_names = ["init_block.weight"] + [
        f"block{s}_{b}.conv1.weight" for s, n in enumerate(STAGE_BLOCKS, start=1) for b in range(1, n + 1)
    ]
    kinds = {name: CARV4[i % 4] for i, name in enumerate(pdc_names)}
    ours = {}
    for name, tensor in official.items():
        if name in kinds:
            if tensor.dim() != 4 or tuple(tensor.shape[2:]) != (3, 3):
                raise ValueError(f"{name} has shape {tuple(tensor.shape)}, expected a 3x3 kernel")
            tensor = convert_pdc(kinds[name], tensor)
        ours[name.replace(".conv.", ".") if name.startswith("conv_reduces.") else name] = tensor
    return ours


def load_pidinet(path: str | Path) -> PiDiNet:
    """The official checkpoint at `path` as an eval-mode `PiDiNet` on the CPU.

    C and D are read from the shapes (``init_block.weight`` is (C, 3, 3, 3),
    ``dilations.0.conv1.weight`` is (D, C, 1, 1)), so the full, -small and -tiny checkpoints
    of every training set load. Raises InputError (one line) when the file is missing, is not
    a torch checkpoint, or holds another network's weights.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, WEIGHTS_MISSING)
    try:
        checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # torch raises many types (pickle, zip, EOF, runtime) for a bad file
        # torch's own messages run to paragraphs (and suggest unsafe loading): name the type only.
        raise InputError(path, f"not a readable torch checkpoint ({type(e).__name__})") from None
    state = checkpoint.get("state_dict", checkpoint) if isinstance(checkpoint, dict) else None
    if not isinstance(state, dict) or not all(isinstance(v, torch.Tensor) for v in state.values()):
        raise InputError(path, "not a PiDiNet checkpoint: expected a state_dict of tensors")
    state = {k.removeprefix("module."): v for k, v in state.items()}
    try:
        channels = state["init_block.weight"].shape[0]
        dil = state["dilations.0.conv1.weight"].shape[0]
        model = PiDiNet(channels, dil)
        model.load_state_dict(_convert_state_dict(state), strict=True)
    except KeyError as e:
        raise InputError(path, f"not a PiDiNet carv4 checkpoint with CDCM and CSAM: no {e.args[0]}") from None
    except (ValueError, RuntimeError, IndexError) as e:  # shapes or key sets of another network
        detail = " ".join(str(e).split())[:300]
        raise InputError(path, f"not a PiDiNet carv4 checkpoint with CDCM and CSAM: {detail}") from None
    return model.eval().requires_grad_(False)


def pidinet_weights(variant: str, weights: str | Path | None) -> Path:
    """The checkpoint file for `variant` ("bsds", "nyud", "multicue"; also "bsds-small",
    "bsds-tiny").

    `weights` (a file, or a folder holding the official file names) wins; otherwise the
    EDGEDOG_PIDINET environment variable (file or folder); otherwise, for "bsds", the shipped
    weights (`shipped_weights`). Raises InputError with where the official weights are
    published when none of these names an existing file.
    """
    if variant not in PIDINET_FILES:
        raise ValueError(f"unknown PiDiNet variant {variant!r}; expected one of {sorted(PIDINET_FILES)}")
    filename = PIDINET_FILES[variant]
    source = weights if weights is not None else os.environ.get(WEIGHTS_ENV) or None
    if source is None and variant == SHIPPED_VARIANT:
        return shipped_weights()
    if source is None:
        raise InputError(filename, WEIGHTS_MISSING)
    path = Path(source).expanduser()
    if path.is_dir():
        path = path / filename
    if not path.is_file():
        raise InputError(path, WEIGHTS_MISSING)
    return path


def shipped_weights() -> Path:
    """The BSDS weights installed with edgedog, after checking their SHA-256 against
    SHIPPED_SHA256: InputError (one line, naming the file) when they are missing or differ."""
    path = SHIPPED_WEIGHTS
    if not path.is_file():
        raise InputError(path, "the PiDiNet weights that ship with edgedog are missing: reinstall "
                               "edgedog, or pass --weights PATH")
    digest = _sha256(path)
    if digest != SHIPPED_SHA256:
        raise InputError(path, f"SHA-256 {digest[:16]}... is not that of the official BSDS weights "
                               f"edgedog ships ({SHIPPED_SHA256[:16]}...): the file is damaged or was "
                               "replaced; reinstall edgedog, or pass --weights PATH")
    return path


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


class PidinetDetector(EdgeDetector):
    """PiDiNet edge probabilities from an official checkpoint.

    Args:
        weights: the checkpoint (see `pidinet_weights`).
        output: "fused" (the network's final map) or one of the side maps "side1" (finest)
            .. "side4" (coarsest).

    Attributes:
        name: "pidinet"; callers may set a variant-specific name.
        output: the selected map.
    """

    name = "pidinet"

    def __init__(self, weights: Path, output: str = "fused"):
        if output not in OUTPUTS:
            raise ValueError(f"unknown PiDiNet output {output!r}; expected one of {OUTPUTS}")
        self.weights = Path(weights)
        self.output = output
        # oneDNN runs these (mostly depthwise and 1x1) convs about twice as fast channels-last.
        self.model = load_pidinet(self.weights).to(memory_format=torch.channels_last)
        self._digest = _sha256(self.weights)[:12]
        self._channel = OUTPUTS.index(output)
        self._mean = torch.tensor(MEAN).view(1, 3, 1, 1)
        self._std = torch.tensor(STD).view(1, 3, 1, 1)

    @property
    def fingerprint(self) -> str:
        return f"pidinet-{self._digest}-{self.output}"

    def detect(self, image: np.ndarray) -> np.ndarray:
        """(H, W, 3) float32 RGB in [0, 1] -> (H, W) float32 edge probability in [0, 1].

        The whole image goes through the network at once (no tiling: tiles would change the
        result near their borders: stage 4's CDCM alone reaches 11 * 8 pixels away).
        """
        if image.ndim != 3 or image.shape[2] != 3:
            raise ValueError(f"expected an (H, W, 3) RGB image, got shape {image.shape}")
        with torch.inference_mode():
            x = torch.from_numpy(np.ascontiguousarray(image, dtype=np.float32)).permute(2, 0, 1)[None]
            x = ((x - self._mean) / self._std).contiguous(memory_format=torch.channels_last)
            maps = self.model(x)
            return maps[0, self._channel].numpy().astype(np.float32, copy=True)
