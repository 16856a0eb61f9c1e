import numpy as np
def box(x, r):
    """mean over a (2r+1)^2 window, windows clipped at the image border (mean over valid pixels)."""
    x = np.asarray(x, np.float64)
    def c1(a, axis):
        n = a.shape[axis]
        cs = np.cumsum(a, axis=axis)
        z = np.zeros_like(np.take(cs, [0], axis=axis))
        cs = np.concatenate([z, cs], axis=axis)
        idx = np.arange(n)
        hi = np.minimum(idx + r + 1, n); lo = np.maximum(idx - r, 0)
        return (np.take(cs, hi, axis=axis) - np.take(cs, lo, axis=axis))
    s = c1(c1(x, 0), 1)
    ones = np.ones(x.shape[:2])
    cnt = c1(c1(ones, 0), 1)
    if x.ndim == 3: cnt = cnt[..., None]
    return s / cnt
def gblur(x, s):
    if s <= 0: return np.asarray(x, np.float64)
    r = int(3 * s + 0.5); k = np.exp(-0.5 * (np.arange(-r, r + 1) / s) ** 2); k /= k.sum()
    def c1(a, axis):
        pad = [(0, 0)] * a.ndim; pad[axis] = (r, r)
        ap = np.pad(a, pad, mode='reflect')
        out = np.zeros_like(a, dtype=np.float64)
        for i, kv in enumerate(k):
            sl = [slice(None)] * a.ndim; sl[axis] = slice(i, i + a.shape[axis]); out += kv * ap[tuple(sl)]
        return out
    return c1(c1(np.asarray(x, np.float64), 0), 1)
