"""Tables of relMSE / PT(2n) for a list of methods (functions of the per-seed data dict).
Import `run_table(methods, scenes, budgets)`; methods: dict name -> fn(d, scene, spp, seed) -> image."""
import sys
import numpy as np
from common import *
from base import variants


def data(scene, spp, seed):
    d = load(scene, spp, seed)
    d.update(variants(scene, spp, seed))
    d['_s'], d['_b'], d['_seed'] = scene, spp, seed
    return d


def mk(name, fn):
    """a method whose image is cached under `name`"""
    return lambda d: cached(d['_s'], d['_b'], d['_seed'], name, lambda: fn(d))


def evaluate(methods, scenes=None, budgets=BUDGETS, verbose=True, bias=False, denom='pt2n'):
    scenes = scenes or [s for s in SCENES if all(scene_ready(s, b) for b in budgets)]
    res = {}
    methods = dict(methods)
    methods.setdefault(denom, lambda d: d[denom])
    for b in budgets:
        for s in scenes:
            ref = reference(s)
            imgs = {m: [] for m in methods}
            for seed in SEEDS:
                d = data(s, b, seed)
                for m, f in methods.items():
                    imgs[m].append(f(d))
            for m in methods:
                res[(b, s, m)] = seed_stats(imgs[m], ref)
    if verbose:
        print_table(res, methods, scenes, budgets, bias=bias, denom=denom)
    return res


def print_table(res, methods, scenes, budgets, bias=False, denom='pt2n'):
    for b in budgets:
        print(f'\n== {b}+{b}: relMSE / {denom}' + (' | bias2 / bias2(D_pt2n)' if bias else ''))
        names = list(methods)
        print(f'{"scene":15s}' + ''.join(f'{m[:12]:>13s}' for m in names))
        logs = {m: [] for m in names}
        for s in scenes:
            base = res[(b, s, denom)]['relmse']
            row = f'{s:15s}'
            for m in names:
                r = res[(b, s, m)]['relmse'] / base
                logs[m].append(np.log(r))
                row += f'{r:13.4f}'
            print(row)
        print(f'{"geomean":15s}' + ''.join(f'{np.exp(np.mean(logs[m])):13.4f}' for m in names))
        if bias:
            print(f'-- bias2 (absolute x1e4)')
            for s in scenes:
                print(f'{s:15s}' + ''.join(f'{res[(b, s, m)]["bias2"] * 1e4:13.3f}' for m in names))
