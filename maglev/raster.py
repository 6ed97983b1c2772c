"""Figures to PNG bytes for less CPU: text drawn from a cache of rasterised strings, a lean PNG encoder.

matplotlib's Agg renderer lays out and rasterises every glyph of every text on each draw, and
Pillow filters every PNG row five ways before compressing it; in a figure of the study these
are most of its cost (a sweep draws the same tick labels, axis labels and legend entries run
after run).  Here a text is rasterised once per string, font, colour, angle and dpi, onto a
transparent sprite anchored at a whole pixel, and then composited at the text's position
rounded to the pixel (at most half a pixel from where Agg puts it; every text is placed so,
cached or not, so a figure's pixels do not depend on what was drawn before).  The PNG is
written with filter type 0 and zlib level 1: files about as large as Pillow's at level 1, in
about a third of the time.
"""

from __future__ import annotations

import struct
import zlib
from collections import OrderedDict

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg
from matplotlib.figure import Figure

SPRITES = 4096  # texts kept rasterised (a sprite is a few kB)
_sprites: OrderedDict = OrderedDict()  # key -> (RGBA array, column, row of the anchor inside it)


class TextCachingRenderer(RendererAgg):
    """Agg renderer whose texts come from the sprite cache (clipped or TeX texts are drawn by Agg)."""

    def draw_text(self, gc, x, y, s, prop, angle, ismath=False, mtext=None):
        clip_path, _ = gc.get_clip_path()
        if ismath == "TeX" or gc.get_clip_rectangle() is not None or clip_path is not None:
            return super().draw_text(gc, x, y, s, prop, angle, ismath, mtext)
        key = (s, prop, float(angle), ismath, gc.get_antialiased(), gc.get_rgb(), gc.get_alpha(),
               gc.get_forced_alpha(), self.dpi, getattr(mtext, "get_fontfeatures", lambda: None)(),
               getattr(mtext, "get_language", lambda: None)())
        sprite = _sprites.get(key)
        if sprite is None:
            sprite = self._rasterise(gc, s, prop, angle, ismath, mtext)
            _sprites[(*key[:1], prop.copy(), *key[2:])] = sprite  # a copy: a FontProperties can change later
            if len(_sprites) > SPRITES:
                _sprites.popitem(last=False)
        else:
            _sprites.move_to_end(key)
        image, col, row = sprite
        if image.size:
            plain = self.new_gc()  # no clip, alpha 1: the sprite carries the text's alpha
            # draw_image: lower-left corner, y upwards; draw_text's (x, y): the anchor, y downwards
            self.draw_image(plain, round(x) - col, self.height - round(y) - (image.shape[0] - row), image)
            plain.restore()

    def _rasterise(self, gc, s, prop, angle, ismath, mtext) -> tuple[np.ndarray, int, int]:
        """The text drawn by Agg at a whole-pixel anchor on a transparent canvas, cropped to its ink."""
        width, height, _ = self.get_text_width_height_descent(s, prop, ismath)
        reach = int(np.ceil(np.hypot(width, height) + prop.get_size_in_points() * self.dpi / 72)) + 2
        scratch = RendererAgg(2 * reach, 2 * reach, self.dpi)
        RendererAgg.draw_text(scratch, gc, reach, reach, s, prop, angle, ismath, mtext)
        pixels = np.asarray(scratch.buffer_rgba())
        rows = np.flatnonzero(pixels[..., 3].any(axis=1))
        cols = np.flatnonzero(pixels[..., 3].any(axis=0))
        if rows.size == 0:
            return np.zeros((0, 0, 4), np.uint8), 0, 0
        r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
        return pixels[r0:r1, c0:c1][::-1].copy(), reach - int(c0), reach - int(r0)  # rows upwards, as draw_image's


class TextCachingCanvas(FigureCanvasAgg):
    """Agg canvas drawing with :class:`TextCachingRenderer` (kept while the figure's size and dpi are)."""

    _size = None

    def get_renderer(self):
        w, h = self.get_width_height(physical=True)
        if self._size != (w, h, self.figure.dpi):
            self.renderer = TextCachingRenderer(w, h, self.figure.dpi)
            self._size = (w, h, self.figure.dpi)
        return self.renderer


def png(fig: Figure, dpi: float) -> bytes:
    """``fig`` at ``dpi`` as PNG bytes (RGBA, 8 bits per channel)."""
    canvas = fig.canvas if isinstance(fig.canvas, TextCachingCanvas) else TextCachingCanvas(fig)
    kept = fig.dpi
    fig.dpi = dpi
    try:
        canvas.draw()
        pixels = np.asarray(canvas.buffer_rgba())
    finally:
        fig.dpi = kept
    return encode_png(pixels)


def encode_png(pixels: np.ndarray) -> bytes:
    """An (height, width, 4) uint8 RGBA array as PNG bytes: no row filter, zlib level 1."""
    height, width, _ = pixels.shape
    rows = np.zeros((height, 4 * width + 1), np.uint8)  # each row: filter type 0, then its pixels
    rows[:, 1:] = pixels.reshape(height, -1)
    header = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)  # 8-bit RGBA, no interlace
    return b"".join((b"\x89PNG\r\n\x1a\n", _chunk(b"IHDR", header), _chunk(b"IDAT", zlib.compress(rows, 1)),
                     _chunk(b"IEND", b"")))


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
