"""Compute and cache the OIDN variants for every finished (scene, budget, seed).
usage: venv/bin/python base.py [scene ...]"""
import sys
import numpy as np
from common import *

A = lambda d: np.clip(d['albedo'], 0, 1)


def variants(scene, spp, seed):
    d = load(scene, spp, seed)
    c = lambda name, fn: cached(scene, spp, seed, name, fn)
    alb, nrm = A(d), d['normal']
    pa = c('aux_alb', lambda: prefilter_aux(d['albedo'], nrm)[0])
    pn = c('aux_nrm', lambda: prefilter_aux(d['albedo'], nrm)[1])
    ours = np.maximum(d['ours'], 0)
    demod = np.maximum(alb, 0.05)
    V = {
        'D_pt2n': lambda: oidn(d['pt2n'], alb, nrm),
        'D_pt2n_ca': lambda: oidn(d['pt2n'], pa, pn, clean_aux=True),
        'D_pt': lambda: oidn(d['pt'], alb, nrm),
        'D_pt_ca': lambda: oidn(d['pt'], pa, pn, clean_aux=True),
        'D_avg': lambda: oidn(d['avg'], alb, nrm),
        'D_ours': lambda: oidn(ours, alb, nrm),
        'D_ours_ca': lambda: oidn(ours, pa, pn, clean_aux=True),
        'D_ours_na': lambda: oidn(ours),
        'D_ours_dm': lambda: oidn(ours / demod) * demod,
        'D_ours_fast': lambda: oidn(ours, alb, nrm, quality='fast'),
        'X_mix0.75_ca': lambda: oidn(0.75 * d['pt'] + 0.25 * ours, pa, pn, clean_aux=True),
        'X_mix0.5_ca': lambda: oidn(0.5 * d['pt'] + 0.5 * ours, pa, pn, clean_aux=True),
        'var_pt': lambda: load(scene, spp, seed, batches=True)['pt_b'].var(0, ddof=1) / 16,
    }
    return {k: c(k, f) for k, f in V.items()}


if __name__ == '__main__':
    scenes = sys.argv[1:] or SCENES
    for s in scenes:
        for b in BUDGETS:
            if not scene_ready(s, b):
                print('not ready', s, b); continue
            for seed in SEEDS:
                variants(s, b, seed)
            print('done', s, b, flush=True)
    if OIDN_TIME:
        print('oidn calls', len(OIDN_TIME), 'median s', np.median(OIDN_TIME))
