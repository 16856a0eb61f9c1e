"""Reference implementation of the `blend` estimator's recipe (ours and OIDN by shrinkage).

Inputs (all H x W x 3 float32, rows top to bottom, as in the stream file):
  pt       the PT stream mean (stream file channels pt.R/G/B)
  albedo   first-hit albedo (albedo.R/G/B), normal first-hit normal (normal.X/Y/Z)
  ours     `ours` image (cvtrace reconstruct --method ours, R/G/B)
  var      `ours`' predicted variance (its layer variance.R/G/B)

Steps
  1. aux prefilter (OIDN's documented "clean aux" pipeline):
       A = OIDN_RT(color = clamp(albedo, 0, 1), hdr = false, quality = high)       (no other images)
       N = OIDN_RT(normal = normal, output = N, quality = high)                     (normal as the only input)
  2. denoiser input  X = max(0, LAMBDA * pt + (1 - LAMBDA) * max(ours, 0))        LAMBDA = 0.75
     D = OIDN_RT(color = X, albedo = A, normal = N, hdr = true, cleanAux = true, quality = high,
                 inputScale unset (auto exposure))
  3. positive-part James-Stein shrinkage of D towards ours, on luminance-averaged window statistics:
       e   = ours - D                                  (per channel)
       s_e = box_R( (e_R^2 + e_G^2 + e_B^2) / 3 )      (window mean, (2R+1)^2, R = 7)
       s_v = box_R( KAPPA * (var_R + var_G + var_B) / 3 )                           KAPPA = 2
       w   = clamp(1 - s_v / s_e, 0, 1)    (w = 0 where s_e <= 0 or not finite; var NaN/neg -> 0)
       J   = D + w * e                                 (same w for the three channels)
  4. C = (1 - OMEGA) * J + OMEGA * ours                OMEGA = 0.05
  box_R: the plain mean over the pixels of the (2R+1)x(2R+1) window that lie inside the image
  (windows clipped at the border, divided by the number of valid pixels, no padding).
Output C may be slightly negative where ours is (it is left as is, like ours).
"""
import numpy as np

LAMBDA = 0.75
KAPPA = 2.0
RADIUS = 7
OMEGA = 0.05


def box(x, r):
    x = np.asarray(x, np.float64)

    def c1(a, axis):
        n = a.shape[axis]
        cs = np.cumsum(a, axis=axis)
        cs = np.concatenate([np.zeros_like(np.take(cs, [0], axis=axis)), cs], axis=axis)
        idx = np.arange(n)
        return np.take(cs, np.minimum(idx + r + 1, n), axis=axis) - np.take(cs, np.maximum(idx - r, 0), axis=axis)

    s = c1(c1(x, 0), 1)
    cnt = c1(c1(np.ones(x.shape[:2]), 0), 1)
    return s / (cnt[..., None] if x.ndim == 3 else cnt)


def shrink(ours, var, D, radius=RADIUS, kappa=KAPPA, omega=OMEGA):
    ours = ours.astype(np.float64); D = D.astype(np.float64)
    var = np.where(np.isfinite(var) & (var > 0), var, 0.0).astype(np.float64)
    e = ours - D
    s_e = box((e * e).mean(-1), radius)
    s_v = box(kappa * var.mean(-1), radius)
    with np.errstate(divide='ignore', invalid='ignore'):
        w = np.where(s_e > 0, 1.0 - s_v / s_e, 0.0)
    w = np.clip(np.nan_to_num(w, nan=0.0), 0.0, 1.0)[..., None]
    J = D + w * e
    return ((1 - omega) * J + omega * ours).astype(np.float32), w[..., 0]


def denoiser_input(pt, ours, lam=LAMBDA):
    return np.maximum(0.0, lam * pt + (1 - lam) * np.maximum(ours, 0.0)).astype(np.float32)


def combine(pt, albedo, normal, ours, var, oidn_fn, prefilter_fn):
    """oidn_fn(color, albedo, normal, hdr, clean_aux, quality); prefilter_fn(albedo, normal) -> (A, N)"""
    A, N = prefilter_fn(albedo, normal)
    D = oidn_fn(denoiser_input(pt, ours), A, N, hdr=True, clean_aux=True, quality='high')
    return shrink(ours, var, D)[0], D


if __name__ == '__main__':
    # usage: recipe.py STREAMS.exr OURS.exr OUT.exr   (OURS.exr from `cvtrace reconstruct --method ours`)
    import sys
    from common import read_exr, rgb, write_exr, oidn, prefilter_aux
    s = read_exr(sys.argv[1]); o = read_exr(sys.argv[2])
    pt, alb = rgb(s, 'pt.'), rgb(s, 'albedo.')
    nrm = np.stack([s['normal.' + c] for c in 'XYZ'], -1)
    C, D = combine(pt, alb, nrm, rgb(o), rgb(o, 'variance.'), oidn, prefilter_aux)
    write_exr(sys.argv[3], C)
