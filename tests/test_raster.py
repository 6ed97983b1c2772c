"""Figures to PNG (:mod:`maglev.raster`): the encoder against Pillow's decoder, the cached texts against Agg's."""

from __future__ import annotations

import io

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PIL import Image

from maglev import raster


def _decoded(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGBA"))


def test_encoded_png_decodes_to_the_same_pixels():
    rng = np.random.default_rng(0)
    pixels = rng.integers(0, 256, size=(7, 13, 4), dtype=np.uint8)
    pixels[2:5, 3:9] = (255, 255, 255, 255)  # runs, as a figure's background has
    assert (_decoded(raster.encode_png(pixels)) == pixels).all()


def _text_figure(x: float, y: float, **text) -> Figure:
    fig = Figure(figsize=(2.0, 1.0), dpi=100)
    fig.text(x, y, "Residual p = 0.05 τ", **text)
    return fig


def _agg(fig: Figure) -> np.ndarray:
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba()).copy()


@pytest.mark.parametrize("text", [{}, {"color": "tab:blue", "alpha": 0.5, "fontsize": 14}])
def test_a_text_at_a_whole_pixel_is_agg_s_own_drawing(text):
    """At a whole-pixel anchor (62, 58 px) a text is Agg's drawing of it, composited from the sprite (±1 level
    of rounding), the first time and from the cache."""
    raster._sprites.clear()
    expected = _agg(_text_figure(0.31, 0.42, **text))
    for _ in range(2):
        got = _decoded(raster.png(_text_figure(0.31, 0.42, **text), 100))
        assert np.abs(got.astype(int) - expected).max() <= 1


def _ink(pixels: np.ndarray) -> tuple[np.ndarray, float]:
    dark = 255 - pixels[..., :3].astype(int).min(axis=-1)
    rows, cols = np.flatnonzero(dark.any(axis=1)), np.flatnonzero(dark.any(axis=0))
    return np.array([rows[0], rows[-1], cols[0], cols[-1]]), float(dark.sum())


@pytest.mark.parametrize("text", [{}, {"rotation": 90}, {"rotation": 30, "ha": "right"}])
def test_a_text_between_pixels_is_drawn_within_half_a_pixel_of_agg_s(text):
    """Anywhere else the text is moved to the nearest whole pixel: its ink's box within a pixel of Agg's,
    as much ink; and the same pixels whatever the cache holds."""
    raster._sprites.clear()
    first = _decoded(raster.png(_text_figure(0.3126, 0.4151, **text), 100))  # 62.52, 41.51 px
    box, ink = _ink(_agg(_text_figure(0.3126, 0.4151, **text)))
    got_box, got_ink = _ink(first)
    assert np.abs(got_box - box).max() <= 1 and got_ink == pytest.approx(ink, rel=0.05)
    assert (_decoded(raster.png(_text_figure(0.3126, 0.4151, **text), 100)) == first).all()


def test_png_keeps_the_figure_s_dpi():
    fig = _text_figure(0.5, 0.5)
    assert _decoded(raster.png(fig, 50)).shape == (50, 100, 4) and fig.dpi == 100
