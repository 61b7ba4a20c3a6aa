"""What every fit of the whole model takes: the samples (:class:`FitData`) and how they are
weighted and judged (:class:`FitOptions`), each frozen — in place of keyword bags spread from
call to call."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.identify.segment.persample import PerSample, SampleArray
from dhlog.model.noise import NoiseModel


@dataclass(frozen=True)
class FitData:
    """The samples of a fit: encoder values ``Q`` (m, n) and measured points ``P`` (m, 3), with,
    where the log has them, each sample's covariance ``sample_cov`` ((m, 3) standard deviations
    or (m, 3, 3)), its target ``which`` (m,: 0 the primary, j the j-th extra target), the
    measured orientation ``rotations`` (m, 3, 3) of a 6-DoF target, the joints' speeds
    ``rates`` (m, n: the clock offset fitted too) and the samples that may enter ``keep``
    (m,; None: all)."""

    Q: SampleArray
    P: SampleArray
    sample_cov: FloatArray | None = None
    which: NDArray[np.int64] | None = None
    rotations: FloatArray | None = None
    rates: SampleArray | None = None
    keep: NDArray[np.bool_] | None = None

    @property
    def m(self) -> int:
        """The number of samples."""
        return int(self.Q.shape[0])

    @property
    def per_sample(self) -> int:
        """Residuals a sample gives: 3 (a point), 6 (a point and an orientation)."""
        return 3 if self.rotations is None else 6

    def at(self, pick: NDArray[np.int64]) -> FitData:
        """The samples ``pick``, every per-sample array cut to them."""

        def cut(v: object) -> object:
            if isinstance(v, np.ndarray | PerSample) and v.shape[:1] == (self.m,):
                return v[pick]
            return v

        return FitData(
            self.Q[pick],
            self.P[pick],
            cut(self.sample_cov),  # type: ignore[arg-type]
            cut(self.which),  # type: ignore[arg-type]
            cut(self.rotations),  # type: ignore[arg-type]
            cut(self.rates),  # type: ignore[arg-type]
            cut(self.keep),  # type: ignore[arg-type]
        )

    def strided(self, most: int) -> tuple[NDArray[np.int64], FitData]:
        """At most ``most`` of the samples, evenly strided: their indices and the data cut to
        them."""
        stride = -(-self.m // most) if self.m > most else 1
        pick = np.arange(0, self.m, stride)
        return pick, self.at(pick)

    def kept(self, keep: NDArray[np.bool_] | None) -> FitData:
        """The same samples, ``keep`` the ones that may enter."""
        return replace(self, keep=keep)


@dataclass(frozen=True)
class FitOptions:
    """How a fit weighs and judges the samples: the ``noise`` model (isotropic σ = ``sigma``, m,
    unless the model names its own), the orientations' σ ``sigma_rotation`` (rad; None: their
    scale in the data), encoder scales fitted (``fit_scales``), the outlier cut ``threshold``
    (in σ of the residual norm; inf: none), at most ``max_iterations`` Levenberg–Marquardt
    iterations, and ``subsample``: above this many samples the fit first converges on an evenly
    strided subset."""

    noise: NoiseModel
    sigma: float
    sigma_rotation: float | None = None
    fit_scales: bool = False
    threshold: float = 5.0
    max_iterations: int = 30
    subsample: int = 40000
