"""Time and accuracy of image -> visibility sampling (issue 2 benchmark).

1024^2 image, N_vis = 3.6e4 and 4.4e5 (the paper's fiducial and high-sensitivity data sizes),
1 and 2 threads: ducc0 NUFFT with a reused plan (spiralbayes' fast path), finufft (if
installed), and NumPy FFT + bilinear interpolation (galario's algorithm) with and without 2x
padding. Accuracy: max |V - V_DFT| / max |V_DFT| on 300 baselines against the direct sum.

    python benchmarks/bench_fourier.py
"""

from __future__ import annotations

import time

import numpy as np

from spiralbayes.fourier import ImageSampler, image_axes, sample_image_dft, sample_image_fft_bilinear
from spiralbayes.geometry import ARCSEC, DiscGeometry

N_PIX = 1024
PIXEL = 0.004  # arcsec: Nyquist for 4.2 Mlambda is 0.0245 arcsec
GEOM = DiscGeometry(0.0, 60.0, 0.01, -0.02)


def disc_image() -> np.ndarray:
    l, m = image_axes((N_PIX, N_PIX), PIXEL)
    L, M = np.meshgrid(l, m)
    r = np.hypot(L / np.cos(np.radians(35)), M)
    ring = np.exp(-0.5 * ((r - 0.4) / 0.03) ** 2) + np.exp(-0.5 * (r / 0.1) ** 2)
    spiral = 0.2 * np.cos(3 * np.arctan2(M, L) - 12 * r) * (r < 0.8)
    return (ring * (1 + spiral)) * 1e-4


def baselines(n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    q = 10 ** rng.uniform(np.log10(1.5e4), np.log10(4.2e6), n)
    t = rng.uniform(0, 2 * np.pi, n)
    return q * np.cos(t), q * np.sin(t)


def median_time(fn, repeat: int = 5) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def accuracy(values: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.abs(values - ref)) / np.max(np.abs(ref)))


def main() -> None:
    rng = np.random.default_rng(0)
    image = disc_image()
    print(f"image {N_PIX}^2, pixel {PIXEL} arcsec; times are medians of 5 calls [ms]")
    print(f"{'method':34s} {'N_vis':>8s} {'threads':>7s} {'ms/call':>9s} {'max err/peak':>13s}")
    for n_vis in (36_000, 440_000):
        u, v = baselines(n_vis, rng)
        ref = sample_image_dft(image, PIXEL, u[:300], v[:300], GEOM)
        for nthreads in (1, 2):
            sampler = ImageSampler(u, v, image.shape, PIXEL, GEOM, nthreads=nthreads, epsilon=1e-10)
            t = median_time(lambda: sampler.sample(image))  # noqa: B023  (called in this iteration)
            err = accuracy(sampler.sample(image)[:300], ref)
            print(f"{'ducc0 NUFFT (plan reused)':34s} {n_vis:8d} {nthreads:7d} {t:9.1f} {err:13.1e}")
            sampler6 = ImageSampler(u, v, image.shape, PIXEL, GEOM, nthreads=nthreads, epsilon=1e-6)
            t = median_time(lambda: sampler6.sample(image))  # noqa: B023  (called in this iteration)
            err = accuracy(sampler6.sample(image)[:300], ref)
            print(f"{'ducc0 NUFFT eps=1e-6':34s} {n_vis:8d} {nthreads:7d} {t:9.1f} {err:13.1e}")
            _finufft_row(image, u, v, ref, n_vis, nthreads)
        for pad in (1, 2):
            t = median_time(lambda: sample_image_fft_bilinear(image, PIXEL, u, v, GEOM, pad=pad), repeat=3)  # noqa: B023
            err = accuracy(sample_image_fft_bilinear(image, PIXEL, u[:300], v[:300], GEOM, pad=pad), ref)
            print(f"{f'NumPy FFT + bilinear (pad {pad}x)':34s} {n_vis:8d} {1:7d} {t:9.1f} {err:13.1e}")


def _finufft_row(image, u, v, ref, n_vis, nthreads) -> None:
    try:
        import finufft
    except ImportError:
        return
    ur, vr = GEOM.rotate_uv(u, v)
    scale = 2 * np.pi * PIXEL * ARCSEC
    x, y = np.ascontiguousarray(vr * scale), np.ascontiguousarray(-ur * scale)
    plan = finufft.Plan(2, image.shape, eps=1e-9, isign=1, nthreads=nthreads, upsampfac=1.25)
    plan.setpts(x, y)
    grid = np.ascontiguousarray(image, dtype=complex)
    phase = GEOM.phase_factor(u, v)
    t = median_time(lambda: plan.execute(grid))
    err = accuracy((plan.execute(grid) * phase)[:300], ref)
    print(f"{'finufft eps=1e-9 (plan, upsamp 1.25)':34s} {n_vis:8d} {nthreads:7d} {t:9.1f} {err:13.1e}")


if __name__ == "__main__":
    main()
