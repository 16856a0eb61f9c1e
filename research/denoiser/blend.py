import numpy as np
from filt import box, gblur
def lum(x): return x.mean(-1, keepdims=True)
def js(o, v, D, r, mode='chan', vD=0.0):
    """positive-part James-Stein: D + max(0, 1 - box(v)/box((o-D)^2)) (o-D)"""
    e = o - D
    if mode == 'lum':
        num = box(lum(v), r); den = box(lum(e*e), r)
    else:
        num = box(v, r); den = box(e*e, r)
    w = np.clip(1 - (num + vD) / np.maximum(den, 1e-30), 0, 1)
    return D + w * e, w
def lowres(o, D, s):
    return D + gblur(o - D, s)
def guided(I, p, r, eps):
    """He et al. guided filter per channel: guide I, input p"""
    mI = box(I, r); mp = box(p, r)
    cov = box(I*p, r) - mI*mp; var = box(I*I, r) - mI*mI
    a = cov / (var + eps); b = mp - a*mI
    return box(a, r)*I + box(b, r)
