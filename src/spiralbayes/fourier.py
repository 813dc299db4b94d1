"""Fourier sampling of sky images at arbitrary baselines, and its adjoint.

Image convention (the FITS/CASA display convention, as galario's):

* ``image[iy, ix]`` in Jy/pixel, ``iy`` increasing to the north, ``ix`` increasing to the
  **west**, so that ``imshow(image, origin="lower")`` shows north up, east left.
* The pixel ``(ny // 2, nx // 2)`` is the image centre; pixel offsets
  ``l = -(ix - nx // 2) * pixel_size`` (RA offset, east positive) and
  ``m = (iy - ny // 2) * pixel_size``.
* ``V(u, v) = sum image[iy, ix] exp(+2 pi i (u' l + v' m)) exp(+2 pi i (u dRA + v dDec))``
  with ``(u', v')`` the baselines rotated by ``PA`` (:meth:`.DiscGeometry.rotate_uv`): the image
  is drawn with its major axis to the north and rotated to ``PA`` east of north in uv space,
  then shifted to ``(dRA, dDec)``, as galario's ``sampleImage``.

The fast path is a type-2 non-uniform FFT from ducc0 (Arras et al. 2021) with a plan reused
for fixed baselines: in the measurements recorded in ``docs/performance.md`` it was the fastest
of ducc0, finufft and galario's FFT + bilinear interpolation, and exact to the requested
``epsilon`` (galario's algorithm errs by per cents of the peak unless padded).
:func:`sample_image_dft` is the plain NumPy reference and :func:`sample_image_fft_bilinear`
galario's algorithm, kept for tests and benchmarks.
"""

from __future__ import annotations

import logging

import numpy as np

from .exceptions import ImageGridError, InputError
from .geometry import DiscGeometry
from .units import ARCSEC

__all__ = [
    "ImageSampler",
    "ImageGridError",
    "check_image_grid",
    "dirty_image",
    "image_axes",
    "psf",
    "sample_image",
    "sample_image_dft",
    "sample_image_fft_bilinear",
    "suggest_image_grid",
]

log = logging.getLogger(__name__)

DEFAULT_EPSILON = 1e-10
"""NUFFT accuracy of image sampling (relative to the image's total flux)."""
NUFFT_EPSILON = 1e-9
"""NUFFT accuracy of the polar-quadrature transforms of the spiral model and scan."""


def image_axes(shape, pixel_size):
    """Pixel-centre offsets ``(l, m)`` [arcsec] along the two image axes.

    Returns ``l`` of length ``nx`` (decreasing: east is left) and ``m`` of length ``ny``.
    """
    ny, nx = shape
    l = -(np.arange(nx) - nx // 2) * pixel_size
    m = (np.arange(ny) - ny // 2) * pixel_size
    return l, m


def _as_geometry(geometry, PA, dRA, dDec) -> DiscGeometry:
    if geometry is not None:
        return geometry
    return DiscGeometry(0.0, PA, dRA, dDec)


def check_image_grid(u, v, shape, pixel_size, *, field_of_view: bool = True) -> None:
    """Refuse an image grid too coarse for the longest baseline or too small for the shortest.

    Parameters
    ----------
    u, v : array_like
        Baselines [lambda].
    shape : (ny, nx)
        Image shape [pixels].
    pixel_size : float
        Pixel size [arcsec].

    Raises
    ------
    ImageGridError
        If ``pixel_size > 1 / (2 |u|_max)`` (Nyquist: the longest baseline would alias) or the
        field of view ``min(shape) * pixel_size`` is smaller than ``1 / uv_min`` (the largest
        scale the shortest baseline measures); the message gives the grid that would do.
        ``field_of_view=False`` checks the pixel size only: the NUFFT is exact for any image
        that contains all of the emission, so a compact model needs no larger image, whereas
        FFT-and-interpolate samplers (galario) and dirty images do.
    """
    uvdist = np.hypot(u, v)
    uv_max = float(np.max(np.abs(np.concatenate([np.ravel(u), np.ravel(v)]))))
    uv_min = float(np.min(uvdist[uvdist > 0])) if np.any(uvdist > 0) else np.inf
    pixel_max = 1.0 / (2.0 * uv_max) / ARCSEC
    if pixel_size > pixel_max:
        raise ImageGridError(
            f"pixel size {pixel_size:.4g} arcsec is too coarse for the longest baseline "
            f"({uv_max:.4g} lambda): use pixel_size <= {pixel_max:.4g} arcsec"
        )
    fov_min = 1.0 / uv_min / ARCSEC
    fov = min(shape) * pixel_size
    if field_of_view and fov < fov_min:
        n_needed = int(np.ceil(fov_min / pixel_size))
        raise ImageGridError(
            f"image of {min(shape)} x {pixel_size:.4g} arcsec = {fov:.4g} arcsec is too small for "
            f"the shortest baseline ({uv_min:.4g} lambda, scale {fov_min:.4g} arcsec): "
            f"use at least {n_needed} pixels"
        )


def suggest_image_grid(u, v, oversample: float = 2.0, min_fov: float = 0.0):
    """A grid ``(n, pixel_size [arcsec])`` that passes :func:`check_image_grid`.

    ``oversample`` divides the Nyquist pixel ``1 / (2 uv_max)``; ``n`` is even and at least
    ``max(1 / uv_min, min_fov [arcsec]) / pixel_size``.
    """
    uvdist = np.hypot(u, v)
    uv_max = float(np.max(np.abs(np.concatenate([np.ravel(u), np.ravel(v)]))))
    pixel = 1.0 / (2.0 * uv_max * oversample) / ARCSEC
    fov = max(1.0 / float(np.min(uvdist[uvdist > 0])) / ARCSEC, min_fov)
    n = int(np.ceil(fov / pixel))
    return n + (n % 2), pixel


def _grid_coords(u, v, pixel_size, geometry: DiscGeometry):
    """ducc0 coordinates (radians per pixel index) for ``image[iy, ix]``."""
    ur, vr = geometry.rotate_uv(u, v)
    scale = 2 * np.pi * pixel_size * ARCSEC
    return np.ascontiguousarray(np.stack([vr * scale, -ur * scale], axis=-1))


class ImageSampler:
    """Sample many images at fixed baselines: a ducc0 NUFFT plan built once and reused.

    Parameters
    ----------
    u, v : array_like
        Baselines [lambda].
    shape : (ny, nx)
        Image shape.
    pixel_size : float
        Pixel size [arcsec].
    geometry : DiscGeometry, optional
        Only ``PA``, ``dRA`` and ``dDec`` are used (the image already carries the inclination).
        Alternatively pass ``PA`` [deg], ``dRA``, ``dDec`` [arcsec].
    epsilon : float
        Requested relative accuracy of the NUFFT.
    nthreads : int
        Threads for ducc0 (0: all cores).
    check : {"nyquist", "full", False}
        Run :func:`check_image_grid` first: the pixel size only (default; the NUFFT is
        exact for any image containing all the emission), pixel size and field of view, or
        nothing.
    """

    def __init__(self, u, v, shape, pixel_size, geometry=None, *, PA=0.0, dRA=0.0, dDec=0.0,
                 epsilon: float = DEFAULT_EPSILON, nthreads: int = 1, check="nyquist"):
        import ducc0

        self.u = np.asarray(u, dtype=float)
        self.v = np.asarray(v, dtype=float)
        self.shape = tuple(int(s) for s in shape)
        self.pixel_size = float(pixel_size)
        self.geometry = _as_geometry(geometry, PA, dRA, dDec)
        if check:
            check_image_grid(self.u, self.v, self.shape, self.pixel_size, field_of_view=check == "full")
        coords = _grid_coords(self.u, self.v, self.pixel_size, self.geometry)
        self._plan = ducc0.nufft.plan(nu2u=False, coord=coords, grid_shape=self.shape,
                                      epsilon=epsilon, nthreads=nthreads)
        self._phase = self.geometry.phase_factor(self.u, self.v)

    def sample(self, image) -> np.ndarray:
        """Visibilities [Jy] of ``image`` [Jy/pixel] at the sampler's baselines."""
        image = np.asarray(image)
        if image.shape != self.shape:
            raise InputError(f"image shape {image.shape} differs from the sampler's {self.shape}")
        grid = np.ascontiguousarray(image, dtype=complex)
        return self._plan.u2nu(grid=grid, forward=False) * self._phase

    def adjoint(self, values) -> np.ndarray:
        """``sum_k values_k exp(-2 pi i (u_k l + v_k m))`` on the image grid (complex).

        The exact adjoint of :meth:`sample`; with ``values = w V`` its real part is the
        (unnormalised) dirty image in the sampler's frame.
        """
        points = np.ascontiguousarray(np.asarray(values, dtype=complex) * np.conj(self._phase))
        return self._plan.nu2u(points=points, forward=True)


def sample_image(image, pixel_size, u, v, geometry=None, *, PA=0.0, dRA=0.0, dDec=0.0,
                 epsilon: float = DEFAULT_EPSILON, nthreads: int = 1, check="nyquist") -> np.ndarray:
    """Visibilities [Jy] of a sky image [Jy/pixel] at baselines ``(u, v)`` [lambda].

    See the module docstring for the image orientation and the meaning of ``PA``, ``dRA``,
    ``dDec``. For many images at the same baselines use :class:`ImageSampler`.
    """
    sampler = ImageSampler(u, v, np.shape(image), pixel_size, geometry, PA=PA, dRA=dRA, dDec=dDec,
                           epsilon=epsilon, nthreads=nthreads, check=check)
    return sampler.sample(image)


def dirty_image(u, v, V, weights, shape, pixel_size, *, epsilon: float = 1e-7,
                nthreads: int = 1) -> np.ndarray:
    """Weighted dirty image [Jy/beam] on the sky grid of :func:`image_axes`.

    ``Re sum_k w_k V_k exp(-2 pi i (u_k l + v_k m)) / sum_k w_k``: natural weighting with
    the Hermitian conjugate baselines implied, normalised so that the PSF peaks at 1.
    """
    sampler = ImageSampler(u, v, shape, pixel_size, epsilon=epsilon, nthreads=nthreads, check=False)
    w = np.asarray(weights, dtype=float)
    return sampler.adjoint(w * np.asarray(V)).real / w.sum()


def psf(u, v, weights, shape, pixel_size, **kwargs) -> np.ndarray:
    """Naturally weighted point-spread function (dirty beam), peak 1 at the image centre."""
    return dirty_image(u, v, np.ones(np.shape(u), dtype=complex), weights, shape, pixel_size, **kwargs)


def sample_image_dft(image, pixel_size, u, v, geometry=None, *, PA=0.0, dRA=0.0, dDec=0.0,
                     chunk: int = 2048) -> np.ndarray:
    """Plain NumPy direct Fourier sum: the reference for :func:`sample_image` (slow)."""
    geometry = _as_geometry(geometry, PA, dRA, dDec)
    image = np.asarray(image, dtype=float)
    l, m = image_axes(image.shape, pixel_size)
    keep = image != 0
    iy, ix = np.nonzero(keep)
    lk, mk, flux = l[ix] * ARCSEC, m[iy] * ARCSEC, image[keep]
    ur, vr = geometry.rotate_uv(u, v)
    return point_sources_dft(ur, vr, lk, mk, flux, chunk=chunk) * geometry.phase_factor(u, v)


def point_sources_dft(u, v, x, y, flux, *, chunk: int = 2048) -> np.ndarray:
    """Plain NumPy direct sum ``sum_k flux_k exp(2 pi i (u x_k + v y_k))`` over point sources.

    ``u``, ``v`` [wavelengths] and ``x``, ``y`` [rad] in any one frame; evaluated ``chunk``
    baselines at a time to bound memory. The reference every direct-sum check builds on.
    """
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    out = np.empty(u.size, dtype=complex)
    for start in range(0, u.size, chunk):
        sl = slice(start, start + chunk)
        phase = 2 * np.pi * (np.outer(u[sl], x) + np.outer(v[sl], y))
        out[sl] = np.exp(1j * phase) @ flux
    return out


def sample_image_fft_bilinear(image, pixel_size, u, v, geometry=None, *, PA=0.0, dRA=0.0, dDec=0.0,
                              pad: int = 1) -> np.ndarray:
    """galario's algorithm in NumPy: one 2-D FFT, bilinear interpolation, phase shift.

    Kept as a baseline for benchmarks (Tazzari et al. 2018); ``pad`` zero-pads the image
    by that factor, which reduces its interpolation error. Not exact: use :func:`sample_image`.
    """
    geometry = _as_geometry(geometry, PA, dRA, dDec)
    image = np.asarray(image, dtype=float)
    ny, nx = image.shape
    if pad > 1:
        big = np.zeros((ny * pad, nx * pad))
        big[(ny * pad) // 2 - ny // 2:(ny * pad) // 2 - ny // 2 + ny,
            (nx * pad) // 2 - nx // 2:(nx * pad) // 2 - nx // 2 + nx] = image
        image, (ny, nx) = big, big.shape
    spectrum = np.fft.fftshift(np.fft.fft2(np.fft.ifftshift(image)))
    ur, vr = geometry.rotate_uv(u, v)
    a, b = ur * pixel_size * ARCSEC, vr * pixel_size * ARCSEC
    fx, fy = a * nx + nx // 2, -b * ny + ny // 2
    x0, y0 = np.floor(fx).astype(int), np.floor(fy).astype(int)
    tx, ty = fx - x0, fy - y0
    x1, y1 = (x0 + 1) % nx, (y0 + 1) % ny
    x0, y0 = x0 % nx, y0 % ny
    vis = ((1 - tx) * (1 - ty) * spectrum[y0, x0] + tx * (1 - ty) * spectrum[y0, x1]
           + (1 - tx) * ty * spectrum[y1, x0] + tx * ty * spectrum[y1, x1])
    return vis * geometry.phase_factor(u, v)
