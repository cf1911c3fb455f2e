"""A heads-up display over review video frames, drawn with Pillow.

Why: a chase frame shows where the UAV is and what it has seen, not what it has left; the HUD
adds the numbers a reviewer judges a mission by — budget left (units), energy used and state of
charge, coverage, the action being flown, the wind (an arrow as seen in this view, and its
speed), the simulated time, the map and the policy — and, at the end, how it ended.

:func:`hud_lines` is the text (tested on its own); :class:`Hud` lays it out for one frame size:
a darkened panel top left, a wind compass top right and a status banner at the bottom. Pillow's
bundled font (FreeType, Pillow ≥ 10.1) is sized to the frame; without FreeType, its bitmap font.

Per-frame cost: FreeType takes ~1 ms to rasterise one line here, 6 ms a frame — a tenth of the
3D render. So each character is rasterised once (:class:`_Stamp`), a line's alpha mask is put
together from them and cached by text, and the mask is blended in numpy; panels are darkened by
a bit shift. A frame's HUD costs well under a millisecond.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from PIL import Image, ImageDraw, ImageFont

__all__ = ["Hud", "HudState", "hud_lines", "view_up_heading", "wind_heading"]

TEXT_RGB = (255, 255, 255)
ACCENT_RGB = (255, 215, 60)  # the wind arrow, and a status worth noticing
PANEL_TEMPLATE = "energy 100.0 kJ  SoC 100%"  # the panel's width in most frames


@dataclass
class HudState:
    """What the HUD shows at one frame. Headings are world directions in degrees,
    counter-clockwise from east (x): ``wind_heading`` where the wind blows *to*, ``view_up``
    the direction pointing up in the frame (the chase camera's azimuth, or the onboard camera's
    image up), so the arrow points the way the wind blows in the picture."""

    map_name: str
    policy: str
    time_s: float
    budget_left: float  # units of the env's budget, fractional while a move draws energy
    budget_start: float
    energy_used_j: float
    state_of_charge: float  # 0..1
    coverage: float  # 0..1, target cells seen
    action: str | None = None
    wind_speed: float = 0.0  # m/s
    wind_heading: float = 0.0
    view_up: float = 90.0
    status: str | None = None  # how the mission ended ("landed", "crashed: …"); None in flight


def hud_lines(state: HudState) -> list[str]:
    """The panel's text, top to bottom."""
    action = state.action or "-"
    return [
        f"map {state.map_name} · {state.policy}",
        f"t {state.time_s:6.1f} s   {action}",
        f"budget {state.budget_left:5.1f} / {state.budget_start:g} u",
        f"energy {state.energy_used_j / 1000:5.1f} kJ  SoC {state.state_of_charge:4.0%}",
        f"coverage {state.coverage:4.0%}",
    ]


def wind_heading(wind_vector) -> float:
    """Heading in [0, 360) (deg, counter-clockwise from east) of a world wind velocity (x east,
    y north): where the wind blows to."""
    return math.degrees(math.atan2(float(wind_vector[1]), float(wind_vector[0]))) % 360.0


def view_up_heading(cam_xmat) -> float:
    """World heading that points up in a camera's image: its y axis (``data.cam_xmat`` column
    1) on the ground plane; for a camera looking straight down, that is the image's top."""
    m = np.asarray(cam_xmat, dtype=float).reshape(3, 3)
    return math.degrees(math.atan2(m[1, 1], m[0, 1]))


def _font(size: int):
    try:
        return ImageFont.load_default(size=size)
    except (TypeError, ImportError, OSError):  # Pillow < 10.1, or no FreeType: the bitmap font
        return ImageFont.load_default()


class _Stamp:
    """Text of one font as alpha masks: characters rasterised once, lines cached by text."""

    def __init__(self, font, max_lines: int = 256):
        self.font = font
        self.max_lines = max_lines
        self._glyphs: dict[str, tuple[np.ndarray, int, int, float]] = {}
        self._lines: dict[str, np.ndarray] = {}
        _, top, _, bottom = font.getbbox("Ág|")
        self.height = int(bottom) + 1

    def _glyph(self, ch: str) -> tuple[np.ndarray, int, int, float]:
        """(alpha mask, x offset, y offset, advance) of one character."""
        glyph = self._glyphs.get(ch)
        if glyph is None:
            left, top, right, bottom = (int(v) for v in self.font.getbbox(ch))
            w, h = max(right - left, 0), max(bottom - top, 0)
            image = Image.new("L", (max(w, 1), max(h, 1)))
            ImageDraw.Draw(image).text((-left, -top), ch, 255, self.font)
            mask = np.asarray(image)[:h, :w]
            glyph = self._glyphs[ch] = (mask, left, top, float(self.font.getlength(ch)))
        return glyph

    def width(self, text: str) -> float:
        return sum(self._glyph(ch)[3] for ch in text)

    def mask(self, text: str) -> np.ndarray:
        """(height, width) uint8 alpha of ``text`` drawn from (0, 0) (no kerning: a HUD's
        digits line up better without)."""
        mask = self._lines.get(text)
        if mask is not None:
            return mask
        mask = np.zeros((self.height, int(math.ceil(self.width(text))) + 2), dtype=np.uint8)
        x = 0.0
        for ch in text:
            glyph, left, top, advance = self._glyph(ch)
            h, w = glyph.shape
            x0, y0 = int(round(x)) + left, max(top, 0)
            if h and w and x0 >= 0:
                dst = mask[y0 : y0 + h, x0 : x0 + w]
                np.maximum(dst, glyph[: dst.shape[0], : dst.shape[1]], out=dst)
            x += advance
        if len(self._lines) >= self.max_lines:
            self._lines.clear()
        self._lines[text] = mask
        return mask

    def put(self, out: np.ndarray, xy: tuple[float, float], text: str, rgb) -> None:
        """Blend ``text`` in colour ``rgb`` into ``out`` (uint8 RGB) at ``xy``, clipped."""
        mask = self.mask(text)
        x, y = int(round(xy[0])), int(round(xy[1]))
        h = min(mask.shape[0], out.shape[0] - y)
        w = min(mask.shape[1], out.shape[1] - x)
        if h <= 0 or w <= 0 or x < 0 or y < 0:
            return
        dst = out[y : y + h, x : x + w]
        alpha = mask[:h, :w, None].astype(np.float32) * (1 / 255)
        dst[...] = dst + (np.asarray(rgb, np.float32) - dst) * alpha


class Hud:
    """Draws a :class:`HudState` over (height, width, 3) uint8 frames of one size."""

    def __init__(self, width: int, height: int):
        self.width, self.height = width, height
        self.font_size = max(9, round(height / 27))  # 14 px at 384, 9 px at 240
        self.text = _Stamp(_font(self.font_size))
        self.small = _Stamp(_font(max(8, self.font_size - 2)))
        self.line = max(self.font_size + max(2, self.font_size // 4), self.text.height)
        self.pad = max(3, self.font_size // 3)
        self.radius = max(10, round(height / 18))  # the wind compass

    def panel_box(self, lines: list[str]) -> tuple[int, int, int, int]:
        """(x0, y0, x1, y1) of the text panel, top left: as wide as a typical panel (so it
        does not flicker from frame to frame) or the widest line, if wider."""
        widest = max(self.text.width(t) for t in [*lines, PANEL_TEMPLATE])
        width = min(self.width, round(widest) + 2 * self.pad)
        return 0, 0, width, 2 * self.pad + len(lines) * self.line

    def compass(self) -> tuple[int, int, int]:
        """(x, y, radius) of the wind compass, top right."""
        r = self.radius
        return self.width - r - 2 * self.pad, r + 2 * self.pad, r

    def wind_box(self) -> tuple[int, int, int, int]:
        """(x0, y0, x1, y1) the wind compass and its label cover, top right."""
        cx, cy, r = self.compass()
        label = self.small.width("wind 00.0 m/s")
        x0 = round(min(cx - r, self.width - label - 2) - self.pad)
        return x0, 0, self.width, cy + r + self.pad + self.line

    def banner_box(self, text: str) -> tuple[int, int, int, int]:
        """(x0, y0, x1, y1) of the status banner: centred at the bottom."""
        w = self.text.width(text)
        x0 = max(0, round((self.width - w) / 2) - 2 * self.pad)
        x1 = min(self.width, round((self.width + w) / 2) + 2 * self.pad)
        y1 = self.height - self.pad
        return x0, y1 - self.line - 2 * self.pad, x1, y1

    def draw(self, frame: np.ndarray, state: HudState) -> np.ndarray:
        """A copy of ``frame`` with the HUD drawn over it."""
        out = np.array(frame, dtype=np.uint8, copy=True)
        lines = hud_lines(state)
        pad = self.pad
        x0, y0, _, _ = _darken(out, self.panel_box(lines))
        for i, text in enumerate(lines):
            self.text.put(out, (x0 + pad, y0 + pad + i * self.line), text, TEXT_RGB)
        self._wind(out, _darken(out, self.wind_box()), state)
        if state.status:
            x0, y0, _, _ = _darken(out, self.banner_box(state.status))
            self.text.put(out, (x0 + 2 * pad, y0 + pad), state.status, ACCENT_RGB)
        return out

    def _wind(self, out: np.ndarray, box: tuple[int, int, int, int], state: HudState) -> None:
        """A circle with an arrow the way the wind blows in this view, the speed under it."""
        bx, by, bx1, by1 = box
        sub = out[by:by1, bx:bx1]
        image = Image.fromarray(sub)
        draw = ImageDraw.Draw(image)
        cx, cy, r = self.compass()
        cx, cy = cx - bx, cy - by
        draw.ellipse((cx - r, cy - r, cx + r, cy + r), outline=TEXT_RGB, width=1)
        if state.wind_speed > 0.05:
            theta = math.radians(state.wind_heading - state.view_up)  # ccw from the frame's up
            ux, uy = -math.sin(theta), -math.cos(theta)  # screen x right, y down
            tip = (cx + 0.85 * r * ux, cy + 0.85 * r * uy)
            tail = (cx - 0.85 * r * ux, cy - 0.85 * r * uy)
            width = max(2, r // 8)
            draw.line((tail, tip), fill=ACCENT_RGB, width=width)
            for side in (1, -1):  # the head: two strokes 30° either side of the shaft, back
                wx = -ux * math.cos(0.5) - side * uy * math.sin(0.5)
                wy = -uy * math.cos(0.5) + side * ux * math.sin(0.5)
                end = (tip[0] + 0.4 * r * wx, tip[1] + 0.4 * r * wy)
                draw.line((tip, end), fill=ACCENT_RGB, width=width)
        else:
            draw.ellipse((cx - 2, cy - 2, cx + 2, cy + 2), fill=TEXT_RGB)
        sub[...] = np.asarray(image)
        label = f"wind {state.wind_speed:.1f} m/s"
        w = self.small.width(label)
        x = min(bx + cx - w / 2, self.width - w - 2)
        self.small.put(out, (x, by + cy + r + 2), label, TEXT_RGB)


def _darken(out: np.ndarray, box: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    """Halve the light in ``box`` of ``out`` (a shift: cheaper than blending); return ``box``."""
    x0, y0, x1, y1 = box
    sub = out[y0:y1, x0:x1]
    np.right_shift(sub, 1, out=sub)
    return box
