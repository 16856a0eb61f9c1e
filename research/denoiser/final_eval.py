"""Final evaluation of research40 (ours + OIDN), all 8 bundled scenes, 32+32 and 96+96, 4 seeds.

usage: venv/bin/python final_eval.py [--extra NAME=PATTERN ...] [--only NAME,NAME] [--csv out.csv]
  PATTERN: an EXR path with {scene} {spp} {seed} fields, e.g.
    --extra rust=/tmp/rust/{scene}/spp{spp:05d}/seed-{seed:03d}.exr
  (R,G,B read from it), to evaluate the Rust implementation with the same protocol.
Metrics as crates/eval/src/stats.rs: relMSE (mean over seeds), bias2 = mean_px w*((mean-ref)^2 - var_s/S)
(var_s the seeds' sample variance, S = 4), meanimg = relMSE of the 4-seed mean image.
"""
import sys, json, argparse
import numpy as np
from common import *
from table import data, mk
from blend import js
import recipe

A = lambda d: np.clip(d['albedo'], 0, 1)


def methods():
    M = {
        'pt2n': lambda d: d['pt2n'],
        'ours': lambda d: d['ours'],
        'D_pt2n': lambda d: d['D_pt2n'],            # PT(2n)+OIDN, stream aux as is (brief's baseline)
        'D_pt2n_ca': lambda d: d['D_pt2n_ca'],      # PT(2n)+OIDN, OIDN-prefiltered aux + cleanAux
        'D_pt': lambda d: d['D_pt'],                # OIDN on the PT stream (n spp), stream aux
        'D_pt_ca': lambda d: d['D_pt_ca'],
        'D_avg': lambda d: d['D_avg'],              # OIDN on (PT+CRN)/2
        'D_ours': lambda d: d['D_ours'],            # OIDN on ours, stream aux
        'D_ours_ca': lambda d: d['D_ours_ca'],      # OIDN on ours, prefiltered aux + cleanAux
        'D_ours_na': lambda d: d['D_ours_na'],      # OIDN on ours, no aux
        'D_ours_dm': lambda d: d['D_ours_dm'],      # OIDN on ours/max(albedo,.05), remodulated
        'D_ours_fast': lambda d: d['D_ours_fast'],  # quality fast
        'm50': lambda d: d['X_mix0.5_ca'],          # OIDN on .5 PT + .5 ours (prefiltered aux)
        'm75': lambda d: d['X_mix0.75_ca'],         # OIDN on .75 PT + .25 ours (prefiltered aux)
        'm75raw': mk('X_mix0.75_raw', lambda d: oidn(recipe.denoiser_input(d['pt'], d['ours']), A(d), d['normal'])),
        # brief's naive JS: 7x7 per channel, kappa 1, toward OIDN(PT n) with stream aux
        'jsNaive': lambda d: js(d['ours'], d['ours_var'], d['D_pt'], 3, 'chan')[0],
        'js7x7(m75)': lambda d: js(d['ours'], d['ours_var'], d['X_mix0.75_ca'], 3, 'lum')[0],
        'js15k2(m75)': lambda d: js(d['ours'], 2 * d['ours_var'], d['X_mix0.75_ca'], 7, 'lum')[0],
        'js15k2(D_pt_ca)': lambda d: js(d['ours'], 2 * d['ours_var'], d['D_pt_ca'], 7, 'lum')[0],
        'js15k2(D_ours_ca)': lambda d: js(d['ours'], 2 * d['ours_var'], d['D_ours_ca'], 7, 'lum')[0],
        'final_rawaux': lambda d: recipe.shrink(d['ours'], d['ours_var'], d['m75raw'])[0],
        'final2': lambda d: recipe.shrink(d['ours'], d['ours_var'], 0.5 * (d['D_pt_ca'] + d['X_mix0.5_ca']))[0],
        'FINAL': lambda d: recipe.shrink(d['ours'], d['ours_var'], d['X_mix0.75_ca'])[0],
    }
    return M


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--extra', action='append', default=[])
    ap.add_argument('--only', default=None)
    ap.add_argument('--json', default='final_results.json')
    a = ap.parse_args()
    M = methods()
    for e in a.extra:
        name, pat = e.split('=', 1)
        M[name] = (lambda pat: lambda d: rgb(read_exr(pat.format(scene=d['_s'], spp=d['_b'], seed=d['_seed']))))(pat)
    if a.only:
        keep = set(a.only.split(',')) | {'pt2n', 'ours', 'D_pt2n', 'D_pt2n_ca'}
        M = {k: v for k, v in M.items() if k in keep}
    res = {}
    for b in BUDGETS:
        for s in SCENES:
            ref = reference(s)
            imgs = {m: [] for m in M}
            for seed in SEEDS:
                d = data(s, b, seed)
                d['m75raw'] = M['m75raw'](d) if 'm75raw' in M else None
                for m, f in M.items():
                    imgs[m].append(f(d))
            for m in M:
                res[(b, s, m)] = seed_stats(imgs[m], ref)
            print('.', end='', flush=True)
    print()
    json.dump({f'{b}|{s}|{m}': v for (b, s, m), v in res.items()}, open(a.json, 'w'), indent=1)
    report(res, list(M))


def gm(x):
    return float(np.exp(np.mean(np.log(x))))


def report(res, names):
    for b in BUDGETS:
        print(f'\n### {b}+{b}: relMSE / PT(2n) relMSE (mean of 4 seeds each)')
        print('| method | ' + ' | '.join(SCENES) + ' | geomean |')
        print('|---' * (len(SCENES) + 2) + '|')
        for m in names:
            r = [res[(b, s, m)]['relmse'] / res[(b, s, 'pt2n')]['relmse'] for s in SCENES]
            print(f'| {m} | ' + ' | '.join(f'{x:.4f}' for x in r) + f' | {gm(r):.4f} |')
        print(f'\n### {b}+{b}: PT(2n) relMSE (absolute)')
        print(' '.join(f'{s}={res[(b, s, "pt2n")]["relmse"]:.5g}' for s in SCENES))
    main_m = [m for m in names if m in ('ours', 'D_pt2n', 'D_pt2n_ca', 'D_pt', 'D_pt_ca', 'm75', 'jsNaive',
                                        'final2', 'final_rawaux', 'FINAL') or m not in methods()]
    for b in BUDGETS:
        for base in ['D_pt2n', 'D_pt2n_ca']:
            print(f'\n### {b}+{b}: relMSE / min(ours, {base}) per scene')
            print('| method | ' + ' | '.join(SCENES) + ' | geomean | max | scenes <= 1 |')
            print('|---' * (len(SCENES) + 4) + '|')
            for m in main_m:
                r = [res[(b, s, m)]['relmse'] / min(res[(b, s, 'ours')]['relmse'], res[(b, s, base)]['relmse'])
                     for s in SCENES]
                print(f'| {m} | ' + ' | '.join(f'{x:.3f}' for x in r) + f' | {gm(r):.3f} | {max(r):.3f} | {sum(x <= 1 for x in r)}/8 |')
        print(f'\n### {b}+{b}: bias2 x 1e4 (relative, as results.md), and relMSE of the 4-seed mean image x 1e4')
        print('| method | ' + ' | '.join(SCENES) + ' | geomean bias2 / D_pt2n |')
        print('|---' * (len(SCENES) + 2) + '|')
        for m in main_m + ['pt2n']:
            bb = [res[(b, s, m)]['bias2'] for s in SCENES]
            rb = [max(res[(b, s, m)]['bias2'], 1e-12) / max(res[(b, s, 'D_pt2n')]['bias2'], 1e-12) for s in SCENES]
            print(f'| {m} bias2 | ' + ' | '.join(f'{x * 1e4:.3f}' for x in bb) + f' | {gm(rb):.3f} |')
        for m in main_m + ['pt2n']:
            mi = [res[(b, s, m)]['meanimg'] for s in SCENES]
            rm = [res[(b, s, m)]['meanimg'] / res[(b, s, 'D_pt2n')]['meanimg'] for s in SCENES]
            print(f'| {m} mean-image relMSE | ' + ' | '.join(f'{x * 1e4:.3f}' for x in mi) + f' | {gm(rm):.3f} (ratio to D_pt2n) |')


if __name__ == '__main__':
    main()
