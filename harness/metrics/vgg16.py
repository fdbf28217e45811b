"""The VGG16 trunk of LPIPS v0.1 and its input scaling, built straight from converted weights.

The layers and their names are those of ``lpips.pretrained_networks.vgg16`` (torchvision's
``vgg16().features[:30]`` cut into five slices ending at relu1_2, relu2_2, relu3_3, relu4_3 and
relu5_3), so a state dict of one loads into the other with ``strict=True`` and both compute the same
operations on the same tensors. What differs is construction: the modules are created on torch's
``meta`` device and the weights *assigned* (``load_state_dict(..., assign=True)``), so there is no
random initialisation of 138 M parameters (torchvision builds the classifier too) and neither
torchvision nor lpips is imported: 3.8 CPU-s less per worker that scores LPIPS.

:data:`SHIFT` / :data:`SCALE` are ``lpips.ScalingLayer``'s buffers, built the same way (float32 from
the same decimal literals); :func:`scale_input` is its ``(x − shift) / scale``.
"""

from __future__ import annotations

import torch
from torch import nn

#: (in, out) channels of the 13 convolutions, "M" a 2×2 max-pool (torchvision's VGG16 "D" config)
LAYOUT = (64, 64, "M", 128, 128, "M", 256, 256, 256, "M", 512, 512, 512, "M", 512, 512, 512)
#: index of the last layer (a ReLU) of each slice in torchvision's ``features``, plus one
SLICE_ENDS = (4, 9, 16, 23, 30)
SHIFT = (-0.030, -0.088, -0.188)
SCALE = (0.458, 0.448, 0.450)


def _features() -> list[nn.Module]:
    layers: list[nn.Module] = []
    channels = 3
    for v in LAYOUT:
        if v == "M":
            layers.append(nn.MaxPool2d(kernel_size=2, stride=2))
        else:
            layers += [nn.Conv2d(channels, v, kernel_size=3, padding=1), nn.ReLU(inplace=True)]
            channels = v
    return layers


class VGG16Trunk(nn.Module):
    """``forward(x) -> (relu1_2, relu2_2, relu3_3, relu4_3, relu5_3)``; parameters named
    ``slice{k}.{i}.weight|bias`` with ``i`` the layer's index in torchvision's ``features``."""

    def __init__(self):
        super().__init__()
        layers = _features()
        start = 0
        for k, end in enumerate(SLICE_ENDS, 1):
            block = nn.Sequential()
            for i in range(start, end):
                block.add_module(str(i), layers[i])
            self.add_module(f"slice{k}", block)
            start = end

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, ...]:
        outs = []
        for k in range(1, len(SLICE_ENDS) + 1):
            x = getattr(self, f"slice{k}")(x)
            outs.append(x)
        return tuple(outs)


def vgg16_trunk(state: dict | None = None) -> VGG16Trunk:
    """The trunk on the ``meta`` device (shapes only), or with ``state`` assigned (its tensors become
    the parameters; every key must match, ``strict``), frozen for inference."""
    with torch.device("meta"):
        trunk = VGG16Trunk()
    if state is not None:
        trunk.load_state_dict(state, strict=True, assign=True)
    return trunk.requires_grad_(False).eval()


def scale_input(x: torch.Tensor) -> torch.Tensor:
    """``lpips.ScalingLayer``: ``(x − shift) / scale`` per channel of an NCHW tensor in [−1, 1]."""
    shift = torch.tensor(SHIFT, dtype=torch.float32, device=x.device)[None, :, None, None]
    scale = torch.tensor(SCALE, dtype=torch.float32, device=x.device)[None, :, None, None]
    return (x - shift) / scale
