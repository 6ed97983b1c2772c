"""One SISO input-output record (MATLAB's ``iddata`` for a single channel).

`IOData` holds the input ``u``, the output ``y`` and the sampling period ``Ts`` of
one experiment, checks them once on construction and offers the preprocessing the
lab uses: mean removal (``detrend``), cutting off the start-up transient (``trim``),
the estimation/validation split (``split``) and decimation.  Loading from the lab's
``.mat`` and CSV files lives here too, because the files are messy (row or column
vectors, ``uint8`` inputs, ``Ts`` missing) and every error must name the file and
variable at fault.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy import signal

MIN_SAMPLES = 10


def _as_vector(values, what: str, source: str) -> np.ndarray:
    """Return ``values`` as a 1-D float64 array, or say clearly why it cannot be one."""
    if isinstance(values, np.ma.MaskedArray):
        masked = np.flatnonzero(np.ma.getmaskarray(values))
        if masked.size:
            raise ValueError(f"{source}: {what} is a masked array with {masked.size} masked value(s), first at "
                             f"index {int(masked[0])}; expected plain numbers (drop those samples, or fill them "
                             "with .filled(value) if that value is what was measured)")
        values = np.ma.getdata(values)
    arr = np.asarray(values)
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise ValueError(f"{source}: {what} must be numeric, got dtype {arr.dtype}")
    if np.iscomplexobj(arr):
        raise ValueError(f"{source}: {what} must be real, got complex values")
    if arr.ndim == 0:
        raise ValueError(f"{source}: {what} must be a vector, got a scalar")
    if arr.ndim > 1:
        if sum(s > 1 for s in arr.shape) > 1:
            raise ValueError(
                f"{source}: {what} must be a vector (one channel), got shape {arr.shape}"
            )
        arr = arr.reshape(-1)
    arr = arr.astype(np.float64)
    bad = ~np.isfinite(arr)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"{source}: {what} has {int(bad.sum())} NaN/inf value(s), first at index {first}; "
            "expected finite numbers"
        )
    return arr


def _without_unit(column: str) -> str:
    """A CSV header's column name without a trailing unit: ``"u (A)"`` → ``"u"``."""
    name = str(column).strip()
    return name[: name.rindex("(")].strip() if name.endswith(")") and "(" in name[1:] else name


def _time_step(t: np.ndarray, source: str) -> float:
    """The sampling period of a uniform time column (seconds); a clear error if it is not uniform."""
    steps = np.diff(t)
    if t.size < 2 or not np.all(np.isfinite(steps)):
        raise ValueError(f"{source}: time column 't' must hold at least two numbers (seconds)")
    ts = float(np.median(steps))
    if not ts > 0 or np.max(np.abs(steps - ts)) > 1e-6 * ts:
        raise ValueError(f"{source}: time column 't' is not uniformly spaced (steps {steps.min():g} to "
                         f"{steps.max():g} s); pass Ts=")
    return float(f"{ts:.12g}")  # the printed times' rounding removed (1 ms, not 0.0009999999999998899)


@dataclass(frozen=True, eq=False)
class IOData:
    """A single-input single-output record sampled every ``Ts`` seconds.

    ``u_offset``/``y_offset`` are the levels removed by :meth:`detrend` (zero for raw
    data); adding them back gives the physical signals.
    """

    u: np.ndarray
    y: np.ndarray
    Ts: float
    name: str | None = None
    u_offset: float = 0.0
    y_offset: float = 0.0
    meta: dict = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        src = self.name or "IOData"
        u = _as_vector(self.u, "input u", src)
        y = _as_vector(self.y, "output y", src)
        if u.size != y.size:
            raise ValueError(
                f"{src}: input u has {u.size} samples but output y has {y.size}; "
                "expected the same length"
            )
        if u.size < MIN_SAMPLES:
            raise ValueError(f"{src}: {u.size} samples is too few; expected at least {MIN_SAMPLES}")
        Ts = _checked_ts(self.Ts, src)
        u.setflags(write=False)
        y.setflags(write=False)
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "Ts", Ts)

    def __eq__(self, other: object) -> bool:
        """Same samples, sampling period, name and offsets (``meta`` is not compared)."""
        if not isinstance(other, IOData):
            return NotImplemented
        return (np.array_equal(self.u, other.u) and np.array_equal(self.y, other.y)
                and (self.Ts, self.name, self.u_offset, self.y_offset)
                == (other.Ts, other.name, other.u_offset, other.y_offset))

    __hash__ = None  # type: ignore[assignment]  (holds arrays)

    # ------------------------------------------------------------------ loading
    @classmethod
    def from_mat(
        cls,
        path: str | Path,
        u: str = "u",
        y: str = "y",
        Ts: float | None = None,
        name: str | None = None,
    ) -> "IOData":
        """Load a MATLAB ``.mat`` file holding the input ``u`` and output ``y`` variables.

        ``Ts`` is read from the file's ``Ts`` variable unless given; a file without one
        needs ``Ts=`` (the lab's ``binary_signal_1`` has none).
        """
        from scipy.io import loadmat, whosmat

        path = _file_path(path, "IOData.from_mat")
        if not path.is_file():
            raise ValueError(f"{path}: no such file")
        try:
            content = loadmat(path)
        except NotImplementedError:
            raise ValueError(
                f"{path}: MATLAB v7.3 (HDF5) files are not supported; save with -v7"
            ) from None
        except Exception as exc:  # scipy raises several types for a corrupt file
            raise ValueError(f"{path}: cannot read as a .mat file ({exc})") from None
        variables = sorted(k for k in content if not k.startswith("__"))
        for var in (u, y):
            if var not in content:
                raise ValueError(
                    f"{path}: no variable {var!r}; the file holds {variables}. "
                    "Pass u=/y= with the right names"
                )
        if Ts is None:
            if "Ts" not in content:
                raise ValueError(
                    f"{path}: no variable 'Ts' in the file (it holds {variables}); pass Ts= explicitly"
                )
            ts_arr = np.asarray(content["Ts"]).reshape(-1)
            if ts_arr.size != 1:
                raise ValueError(f"{path}: variable 'Ts' must be a scalar, got shape {content['Ts'].shape}")
            kind = dict((var, cls) for var, _, cls in whosmat(path)).get("Ts")  # loadmat reads a logical as uint8
            if kind in ("logical", "char") or not np.issubdtype(ts_arr.dtype, np.number):
                raise ValueError(f"{path}: variable 'Ts' is {kind or ts_arr.dtype} ({ts_arr[0].item()!r}); expected the "
                                 "sampling period in seconds as a number")
            Ts = float(ts_arr[0])
        label = name or path.stem
        return cls(
            u=_as_vector(content[u], f"variable {u!r}", str(path)),
            y=_as_vector(content[y], f"variable {y!r}", str(path)),
            Ts=_checked_ts(Ts, str(path)),
            name=label,
            meta={"source": str(path)},
        )

    @classmethod
    def from_csv(
        cls,
        path: str | Path,
        u: str = "u",
        y: str = "y",
        Ts: float | None = None,
        name: str | None = None,
    ) -> "IOData":
        """Load a CSV file with a header row naming the input and output columns.

        A column may carry its unit in the header: ``u (A)`` is column ``u``.  The
        sampling period is ``Ts`` (seconds) if given, else a ``Ts`` column with a
        constant value, else the spacing of a time column ``t`` (seconds, uniform), as
        ``maglev labdata`` writes them (``t (s),u (A),y (cm)``).
        """
        import pandas as pd

        path = _file_path(path, "IOData.from_csv")
        if not path.is_file():
            raise ValueError(f"{path}: no such file")
        try:
            frame = pd.read_csv(path)
        except Exception as exc:
            raise ValueError(f"{path}: cannot read as CSV ({exc})") from None
        frame.columns = [_without_unit(c) if _without_unit(c) not in frame.columns else c for c in frame.columns]
        for col in (u, y):
            if col not in frame.columns:
                raise ValueError(
                    f"{path}: no column {col!r}; the header has {list(frame.columns)}. "
                    "Pass u=/y= with the right names"
                )
        if Ts is None and "Ts" not in frame.columns and "t" in frame.columns:
            Ts = _time_step(pd.to_numeric(frame["t"], errors="coerce").to_numpy(dtype=float), str(path))
        if Ts is None:
            if "Ts" not in frame.columns:
                raise ValueError(f"{path}: CSV has no sampling period; pass Ts= (seconds), or add a Ts "
                                 "column or a time column t")
            values = pd.to_numeric(frame["Ts"], errors="coerce").dropna().unique()
            if values.size != 1:
                raise ValueError(f"{path}: column 'Ts' must hold one constant sampling period, got "
                                 f"{values.size} different values ({', '.join(f'{v:g}' for v in values[:4])}"
                                 f"{', ...' if values.size > 4 else ''})")
            Ts = float(values[0])
        for col in (u, y):
            values = pd.to_numeric(frame[col], errors="coerce")
            bad = values.isna() & frame[col].notna()
            if bad.any():
                row = int(np.flatnonzero(bad.to_numpy())[0])
                raise ValueError(
                    f"{path}: column {col!r} row {row + 2} is {frame[col].iloc[row]!r}; expected a number"
                )
        return cls(
            u=_as_vector(frame[u].to_numpy(dtype=float), f"column {u!r}", str(path)),
            y=_as_vector(frame[y].to_numpy(dtype=float), f"column {y!r}", str(path)),
            Ts=_checked_ts(Ts, str(path)),
            name=name or path.stem,
            meta={"source": str(path)},
        )

    # ------------------------------------------------------------------ basics
    def __len__(self) -> int:
        return self.u.size

    @property
    def N(self) -> int:
        """Number of samples."""
        return self.u.size

    @property
    def t(self) -> np.ndarray:
        """Sample times in seconds, starting at 0."""
        return np.arange(self.N) * self.Ts

    def __repr__(self) -> str:
        label = f" {self.name!r}" if self.name else ""
        return f"IOData{label}(N={self.N}, Ts={self.Ts:g})"

    # ------------------------------------------------------------------ preprocessing
    def detrend(self) -> "IOData":
        """Remove the means of u and y; the removed levels accumulate in the offsets."""
        mu, my = float(self.u.mean()), float(self.y.mean())
        return replace(
            self,
            u=self.u - mu,
            y=self.y - my,
            u_offset=self.u_offset + mu,
            y_offset=self.y_offset + my,
        )

    def trim(self, n_or_fraction: int | float) -> "IOData":
        """Drop the first samples: an integer count, or a fraction in [0, 1) of the record."""
        n = _count(n_or_fraction, self.N, "trim", self.name)
        if self.N - n < MIN_SAMPLES:
            raise ValueError(
                f"{self.name or 'IOData'}: trimming {n} of {self.N} samples leaves fewer than {MIN_SAMPLES}"
            )
        return replace(self, u=self.u[n:], y=self.y[n:])

    def segment(self, start: int, stop: int | None = None) -> "IOData":
        """Samples ``start:stop`` as a new record (same Ts and offsets)."""
        return replace(self, u=self.u[start:stop], y=self.y[start:stop])

    def split(self, fraction: float = 0.5) -> tuple["IOData", "IOData"]:
        """Return (estimation, validation): the first ``fraction`` of the record and the rest."""
        src = self.name or "IOData"
        if not (isinstance(fraction, (int, float)) and 0 < fraction < 1):
            raise ValueError(f"{src}: split fraction must be in (0, 1), got {fraction!r}")
        n = int(round(self.N * fraction))
        if n < MIN_SAMPLES or self.N - n < MIN_SAMPLES:
            raise ValueError(
                f"{src}: splitting {self.N} samples at {fraction} leaves a part with fewer than "
                f"{MIN_SAMPLES} samples"
            )
        est = replace(self, u=self.u[:n], y=self.y[:n], name=f"{src}[est]")
        val = replace(self, u=self.u[n:], y=self.y[n:], name=f"{src}[val]")
        return est, val

    def decimate(self, k: int) -> "IOData":
        """Keep every k-th sample after an anti-aliasing filter (like MATLAB's ``idresamp``/``decimate``).

        Both signals go through the same 8th-order Chebyshev type I low-pass
        (``scipy.signal.decimate``, zero phase), so the input-output relation below
        the new Nyquist frequency is kept.
        """
        src = self.name or "IOData"
        if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)) or k < 1:
            raise ValueError(f"{src}: decimation factor must be a positive integer, got {k!r}")
        if k == 1:
            return self
        if self.N // k < MIN_SAMPLES:
            raise ValueError(f"{src}: decimating {self.N} samples by {k} leaves too few samples")
        u = signal.decimate(self.u, int(k), ftype="iir", zero_phase=True)
        y = signal.decimate(self.y, int(k), ftype="iir", zero_phase=True)
        return replace(self, u=u, y=y, Ts=self.Ts * k)

    def to_dict(self) -> dict:
        """Plain-Python summary (for logging), without the samples."""
        return {
            "name": self.name,
            "N": self.N,
            "Ts": self.Ts,
            "u_offset": self.u_offset,
            "y_offset": self.y_offset,
        }


def _file_path(path, what: str) -> Path:
    """``path`` as a Path, or a ValueError saying a file path was expected (an int is no path)."""
    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"{what}: path must be a file path (str or pathlib.Path), got {path!r}")
    return Path(path)


def _checked_ts(Ts, source: str) -> float:
    """``Ts`` as a positive finite float (seconds), or a ValueError naming the source; a bool or a string is no period."""
    if isinstance(Ts, (bool, np.bool_, str, bytes)):
        raise ValueError(f"{source}: Ts must be a positive number of seconds, got {Ts!r}")
    try:
        value = float(Ts)
    except (TypeError, ValueError):
        raise ValueError(f"{source}: Ts must be a positive number of seconds, got {Ts!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"{source}: Ts must be a positive number of seconds, got {Ts!r}")
    return value


def _count(n_or_fraction, total: int, what: str, name: str | None) -> int:
    """Turn an integer count or a fraction of ``total`` into a sample count."""
    src = name or "IOData"
    if isinstance(n_or_fraction, (bool, np.bool_)):
        raise ValueError(f"{src}: {what} takes a sample count or a fraction, got {n_or_fraction!r}")
    if isinstance(n_or_fraction, (int, np.integer)):
        n = int(n_or_fraction)
    elif isinstance(n_or_fraction, (float, np.floating)) and 0 <= n_or_fraction < 1:
        n = int(round(total * float(n_or_fraction)))
    else:
        raise ValueError(
            f"{src}: {what} takes a sample count >= 0 or a fraction in [0, 1), got {n_or_fraction!r}"
        )
    if n < 0 or n >= total:
        raise ValueError(f"{src}: cannot {what} {n} of {total} samples")
    return n
