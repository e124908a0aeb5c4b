"""The part detector: a small YOLO-style network sized for a CPU.

CSP-style backbone (strides 2..32), SPPF at the deepest level, a PAN-style neck (top-down then
bottom-up), and three anchor-free heads at strides 8, 16 and 32. Each head cell predicts the
distances from its centre to the box's four sides (in units of its stride), an objectness logit
and one logit per class. The exported graph also decodes: its single output is
[1, cells, 4 + 1 + classes] with the box as x0, y0, x1, y1 in input pixels and sigmoid scores,
so the Rust side only thresholds and runs non-maximum suppression.
"""

import torch
from torch import nn
import torch.nn.functional as F

STRIDES = (8, 16, 32)


class ConvBnAct(nn.Module):
    """Convolution, batch normalisation, SiLU."""

    def __init__(self, cin, cout, k=1, s=1):
        super().__init__()
        self.conv = nn.Conv2d(cin, cout, k, s, k // 2, bias=False)
        self.bn = nn.BatchNorm2d(cout, eps=1e-3, momentum=0.03)
        self.act = nn.SiLU()

    def forward(self, x):
        return self.act(self.bn(self.conv(x)))


class Bottleneck(nn.Module):
    """1x1 then 3x3 convolution with a residual connection."""

    def __init__(self, c, shortcut=True):
        super().__init__()
        self.cv1 = ConvBnAct(c, c, 1)
        self.cv2 = ConvBnAct(c, c, 3)
        self.shortcut = shortcut

    def forward(self, x):
        y = self.cv2(self.cv1(x))
        return x + y if self.shortcut else y


class CSP(nn.Module):
    """Cross-stage partial block: half the channels pass bottlenecks, half bypass them."""

    def __init__(self, cin, cout, n=1, shortcut=True):
        super().__init__()
        h = cout // 2
        self.cv1 = ConvBnAct(cin, h, 1)
        self.cv2 = ConvBnAct(cin, h, 1)
        self.m = nn.Sequential(*(Bottleneck(h, shortcut) for _ in range(n)))
        self.cv3 = ConvBnAct(2 * h, cout, 1)

    def forward(self, x):
        return self.cv3(torch.cat((self.m(self.cv1(x)), self.cv2(x)), 1))


class SPPF(nn.Module):
    """Spatial pyramid pooling (fast): three chained 5x5 max pools, concatenated."""

    def __init__(self, c):
        super().__init__()
        h = c // 2
        self.cv1 = ConvBnAct(c, h, 1)
        self.cv2 = ConvBnAct(4 * h, c, 1)
        self.pool = nn.MaxPool2d(5, 1, 2)

    def forward(self, x):
        x = self.cv1(x)
        y1 = self.pool(x)
        y2 = self.pool(y1)
        return self.cv2(torch.cat((x, y1, y2, self.pool(y2)), 1))


class Head(nn.Module):
    """One level's prediction: a shared 3x3 convolution, then box, objectness and class."""

    def __init__(self, cin, width, num_classes):
        super().__init__()
        self.stem = ConvBnAct(cin, width, 3)
        self.out = nn.Conv2d(width, 4 + 1 + num_classes, 1)
        nn.init.constant_(self.out.bias, 0.0)
        with torch.no_grad():
            # Start with rare objects (prior 0.01) so the background loss does not swamp training.
            self.out.bias[4:] = -4.6

    def forward(self, x):
        return self.out(self.stem(x))


class Detector(nn.Module):
    """Backbone, neck and heads; `forward` returns raw per-level maps [B, 5 + C, H, W]."""

    def __init__(self, num_classes, widths=(24, 32, 48, 64)):
        super().__init__()
        c2, c3, c4, c5 = widths
        self.num_classes = num_classes
        # Patchify stem: a 4x4 stride-4 convolution sees every pixel once (space-to-depth and a
        # 1x1 mix in one), so no work is spent at full or half resolution.
        self.stem = nn.Sequential(
            nn.Conv2d(3, c2, 4, 4, 0, bias=False), nn.BatchNorm2d(c2, eps=1e-3, momentum=0.03),
            nn.SiLU(),
        )  # /4
        self.down3 = ConvBnAct(c2, c3, 3, 2)  # /8
        self.csp3 = CSP(c3, c3, 1)
        self.down4 = ConvBnAct(c3, c4, 3, 2)  # /16
        self.csp4 = CSP(c4, c4, 1)
        self.down5 = ConvBnAct(c4, c5, 3, 2)  # /32
        self.csp5 = CSP(c5, c5, 1)
        self.sppf = SPPF(c5)
        # Top-down path.
        self.lat5 = ConvBnAct(c5, c4, 1)
        self.td4 = CSP(2 * c4, c4, 1, shortcut=False)
        self.lat4 = ConvBnAct(c4, c3, 1)
        self.td3 = CSP(2 * c3, c3, 1, shortcut=False)
        # Bottom-up path.
        self.bu3 = ConvBnAct(c3, c3, 3, 2)
        self.pan4 = CSP(2 * c3, c4, 1, shortcut=False)
        self.bu4 = ConvBnAct(c4, c4, 3, 2)
        self.pan5 = CSP(c4 + c4, c5, 1, shortcut=False)
        self.heads = nn.ModuleList(
            [Head(c3, c3, num_classes), Head(c4, c4, num_classes), Head(c5, c4, num_classes)]
        )

    def forward(self, x):
        x = self.stem(x)
        p3 = self.csp3(self.down3(x))
        p4 = self.csp4(self.down4(p3))
        p5 = self.sppf(self.csp5(self.down5(p4)))
        l5 = self.lat5(p5)
        t4 = self.td4(torch.cat((F.interpolate(l5, scale_factor=2.0, mode="nearest"), p4), 1))
        l4 = self.lat4(t4)
        n3 = self.td3(torch.cat((F.interpolate(l4, scale_factor=2.0, mode="nearest"), p3), 1))
        n4 = self.pan4(torch.cat((self.bu3(n3), l4), 1))
        n5 = self.pan5(torch.cat((self.bu4(n4), l5), 1))
        return [head(f) for head, f in zip(self.heads, (n3, n4, n5))]


def grid(h, w, stride, device=None):
    """Cell centres of an h x w map in input pixels, flattened row-major: [h * w, 2] (x, y)."""
    ys, xs = torch.meshgrid(
        torch.arange(h, dtype=torch.float32, device=device),
        torch.arange(w, dtype=torch.float32, device=device),
        indexing="ij",
    )
    return torch.stack(((xs + 0.5) * stride, (ys + 0.5) * stride), -1).reshape(-1, 2)


def flatten(maps):
    """Raw maps to [B, cells, 5 + C] plus per-cell centres [cells, 2] and strides [cells]."""
    rows, centres, strides = [], [], []
    for m, s in zip(maps, STRIDES):
        b, c, h, w = m.shape
        rows.append(m.permute(0, 2, 3, 1).reshape(b, h * w, c))
        centres.append(grid(h, w, s, m.device))
        strides.append(torch.full((h * w,), float(s), device=m.device))
    return torch.cat(rows, 1), torch.cat(centres, 0), torch.cat(strides, 0)


def decode_boxes(raw, centres, strides):
    """Side distances (softplus, in strides) to x0, y0, x1, y1 boxes in input pixels."""
    d = F.softplus(raw[..., :4]) * strides[:, None]
    c = centres.unsqueeze(0)
    return torch.cat((c - d[..., :2], c + d[..., 2:]), -1)


class Exported(nn.Module):
    """The deployable graph: input [1, 3, H, W] RGB in 0..1, output [1, cells, 5 + C]."""

    def __init__(self, net, height, width):
        super().__init__()
        self.net = net
        centres, strides = [], []
        for s in STRIDES:
            centres.append(grid(height // s, width // s, s))
            strides.append(torch.full((height // s * (width // s),), float(s)))
        self.register_buffer("centres", torch.cat(centres, 0))
        self.register_buffer("strides", torch.cat(strides, 0))

    def forward(self, x):
        rows = []
        for m in self.net(x):
            b, c, h, w = m.shape
            rows.append(m.reshape(b, c, h * w))
        raw = torch.cat(rows, 2).permute(0, 2, 1)
        boxes = decode_boxes(raw, self.centres, self.strides)
        return torch.cat((boxes, torch.sigmoid(raw[..., 4:])), -1)
