"""Shared I/O, metrics and OIDN wrapper of the research behind `blend` (docs/estimators.md).

Data: $CVTRACE_STUDIES/<scene>/spp000NN/seed-00S.{streams,pt2n}.exr (read-only), the study folders
of `cvtrace study scenes/<scene>/scene.gltf --spp 32,96 --seeds 4 --batches 16 ... -o $CVTRACE_STUDIES/<scene>`.
Cache: $CVTRACE_RESEARCH_CACHE/<scene>/<spp>/seed-S.*.npy
"""
import os, subprocess, time
import numpy as np
import OpenEXR

REPO = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..'))
ROOT = os.environ.get('CVTRACE_STUDIES', os.path.join(REPO, 'out', 'study', 'bundled'))
SCENES = ['cornell-box', 'door-ajar', 'glass-of-water', 'glossy-room', 'sponza', 'engine', 'head', 'teapots']
BUDGETS = [32, 96]
SEEDS = [0, 1, 2, 3]
CVTRACE = os.environ.get('CVTRACE_BIN', os.path.join(REPO, 'target', 'release', 'cvtrace'))
CACHE = os.environ.get('CVTRACE_RESEARCH_CACHE', os.path.join(REPO, '.cache', 'research-denoiser'))
EPS = 0.01


def read_exr(path, names=None):
    f = OpenEXR.File(path, separate_channels=True)
    ch = f.channels()
    if names is None:
        return {k: v.pixels.astype(np.float32) for k, v in ch.items()}
    return {k: ch[k].pixels.astype(np.float32) for k in names}


def rgb(d, prefix=''):
    return np.stack([d[prefix + c] for c in 'RGB'], -1)


def write_exr(path, img):
    h = {'compression': OpenEXR.ZIP_COMPRESSION, 'type': OpenEXR.scanlineimage}
    chans = {c: np.ascontiguousarray(img[..., i].astype(np.float32)) for i, c in enumerate('RGB')}
    with OpenEXR.File(h, chans) as f:
        f.write(path)


def finished(scene, spp, seed):
    d = f'{ROOT}/{scene}/spp{spp:05d}'
    return all(os.path.exists(f'{d}/seed-{seed:03d}.{k}.seconds') for k in ('streams', 'pt2n'))


def scene_ready(scene, spp):
    return all(finished(scene, spp, s) for s in SEEDS)


_ref = {}


def reference(scene):
    if scene not in _ref:
        _ref[scene] = rgb(read_exr(os.path.join(REPO, 'scenes', scene, 'scene.ref.exr')))
    return _ref[scene]


def weights(ref):
    """1/(rbar^2 + 0.01) per pixel, rbar = mean of the reference's three channels."""
    rb = ref.astype(np.float64).mean(-1)
    return 1.0 / (rb * rb + EPS)


def relmse(x, ref):
    w = weights(ref)
    return float(((x.astype(np.float64) - ref) ** 2 * w[..., None]).mean())


def seed_stats(imgs, ref):
    """imgs: list of S images. Returns dict relmse (mean over seeds), bias2, variance, meanimg_relmse
    exactly as crates/eval/src/stats.rs (sample variance over seeds with S-1; bias2 = d^2 - var/S)."""
    S = len(imgs)
    X = np.stack([i.astype(np.float64) for i in imgs])
    w = weights(ref)[..., None]
    rel = [float(((x - ref) ** 2 * w).mean()) for x in X]
    m = X.mean(0)
    var = X.var(0, ddof=1)
    b2 = float((w * ((m - ref) ** 2 - var / S)).mean())
    v = float((w * var).mean())
    return dict(relmse=float(np.mean(rel)), per_seed=rel, bias2=b2, variance=v,
                meanimg=float(((m - ref) ** 2 * w).mean()))


# ---------------------------------------------------------------- data loading with cache

def paths(scene, spp, seed):
    d = f'{ROOT}/{scene}/spp{spp:05d}'
    return f'{d}/seed-{seed:03d}.streams.exr', f'{d}/seed-{seed:03d}.pt2n.exr'


def cdir(scene, spp):
    d = f'{CACHE}/{scene}/{spp}'
    os.makedirs(d, exist_ok=True)
    return d


def load(scene, spp, seed, batches=False):
    """Returns dict: pt, crn, avg, albedo, normal, depth, pt2n, ours, ours_var (H,W,3 float32);
    with batches=True also pt_b, crn_b (16,H,W,3)."""
    d = cdir(scene, spp)
    base = f'{d}/seed-{seed}'
    keys = ['pt', 'crn', 'albedo', 'normal', 'depth', 'pt2n', 'ours', 'ours_var']
    if not all(os.path.exists(f'{base}.{k}.npy') for k in keys) or batches:
        sp, p2 = paths(scene, spp, seed)
        s = read_exr(sp)
        out = dict(pt=rgb(s, 'pt.'), crn=rgb(s, 'crn.'), albedo=rgb(s, 'albedo.'),
                   normal=np.stack([s['normal.' + c] for c in 'XYZ'], -1), depth=s['depth.Z'])
        out['pt2n'] = rgb(read_exr(p2))
        if batches:
            out['pt_b'] = np.stack([rgb(s, f'pt.b{b:02d}.') for b in range(16)])
            out['crn_b'] = np.stack([rgb(s, f'crn.b{b:02d}.') for b in range(16)])
        if not os.path.exists(f'{base}.ours.npy'):
            o = f'{base}.ours.exr'
            subprocess.run([CVTRACE, 'reconstruct', sp, '--method', 'ours', '-o', o, '--force',
                            '--log', 'warn', '-t', '2'], check=True, stdout=subprocess.DEVNULL)
            r = read_exr(o)
            np.save(f'{base}.ours.npy', rgb(r))
            np.save(f'{base}.ours_var.npy', rgb(r, 'variance.'))
            os.remove(o)
        for k in ['pt', 'crn', 'albedo', 'normal', 'depth', 'pt2n']:
            if not os.path.exists(f'{base}.{k}.npy'):
                np.save(f'{base}.{k}.npy', out[k])
        for k in ['ours', 'ours_var']:
            out[k] = np.load(f'{base}.{k}.npy')
        out['avg'] = 0.5 * (out['pt'] + out['crn'])
        return out
    out = {k: np.load(f'{base}.{k}.npy') for k in keys}
    out['avg'] = 0.5 * (out['pt'] + out['crn'])
    return out


# ---------------------------------------------------------------- OIDN

import pyoidn
from pyoidn.capi import oidn_Capi
from pyoidn.utils import c_str

_dev = None
OIDN_TIME = []


def _device():
    global _dev
    if _dev is None:
        _dev = pyoidn.Device(pyoidn.OIDN_DEVICE_TYPE_CPU)
        _dev.set_int('numThreads', 2)
        _dev.commit()
    return _dev


QUAL = {'high': pyoidn.OIDN_QUALITY_HIGH, 'balanced': pyoidn.OIDN_QUALITY_BALANCED,
        'fast': pyoidn.OIDN_QUALITY_FAST}


def oidn(color, albedo=None, normal=None, hdr=True, clean_aux=False, quality='high',
         input_scale=None, filter_type='RT'):
    """OIDN 2.5.1 on the CPU. color (H,W,3) float32 >= 0. Returns the denoised image."""
    dev = _device()
    color = np.ascontiguousarray(np.maximum(color, 0).astype(np.float32))
    out = np.zeros_like(color)
    flt = pyoidn.Filter(dev, filter_type)
    flt.set_image(pyoidn.OIDN_IMAGE_COLOR, color, pyoidn.OIDN_FORMAT_FLOAT3)
    keep = [color]
    if albedo is not None:
        a = np.ascontiguousarray(albedo.astype(np.float32)); keep.append(a)
        flt.set_image(pyoidn.OIDN_IMAGE_ALBEDO, a, pyoidn.OIDN_FORMAT_FLOAT3)
    if normal is not None:
        n = np.ascontiguousarray(normal.astype(np.float32)); keep.append(n)
        flt.set_image(pyoidn.OIDN_IMAGE_NORMAL, n, pyoidn.OIDN_FORMAT_FLOAT3)
    flt.set_image(pyoidn.OIDN_IMAGE_OUTPUT, out, pyoidn.OIDN_FORMAT_FLOAT3)
    if filter_type == 'RT':
        flt.set_bool('hdr', bool(hdr))
        flt.set_bool('cleanAux', bool(clean_aux))
    flt.set_int('quality', QUAL[quality])
    if input_scale is not None:
        flt.set_float('inputScale', float(input_scale))
    flt.commit()
    t = time.perf_counter()
    flt.execute()
    OIDN_TIME.append(time.perf_counter() - t)
    err = dev.get_error()
    flt.release()
    if err is not None:
        raise RuntimeError(err)
    return out


def prefilter_aux(albedo, normal, quality='high'):
    """OIDN's documented aux prefiltering (README "denoising with prefiltering"): an RT filter with
    the albedo as its only input image `albedo` (clamped to [0,1]) and output, and one with the normal
    as its only input image `normal`; then the main filter runs with cleanAux = true."""
    return _oidn_aux('albedo', np.clip(albedo, 0, 1), quality), _oidn_aux('normal', normal, quality)


def _oidn_normal(normal, quality='high'):
    return _oidn_aux('normal', normal, quality)


def _oidn_aux(slot, img, quality='high'):
    dev = _device()
    nrm = np.ascontiguousarray(img.astype(np.float32))
    out = np.zeros_like(nrm)
    flt = pyoidn.Filter(dev, 'RT')
    flt.set_image(slot, nrm, pyoidn.OIDN_FORMAT_FLOAT3)
    flt.set_image(pyoidn.OIDN_IMAGE_OUTPUT, out, pyoidn.OIDN_FORMAT_FLOAT3)
    flt.set_int('quality', QUAL[quality])
    flt.commit(); flt.execute()
    err = dev.get_error(); flt.release()
    if err is not None:
        raise RuntimeError(err)
    return out


def cached(scene, spp, seed, name, fn):
    p = f'{cdir(scene, spp)}/seed-{seed}.{name}.npy'
    if os.path.exists(p):
        return np.load(p)
    x = fn().astype(np.float32)
    np.save(p, x)
    return x


def ours_variant(scene, spp, seed, name, params, method='ours'):
    """cvtrace reconstruct with --param list, cached as <name>.npy and <name>_var.npy"""
    base = f'{cdir(scene, spp)}/seed-{seed}'
    if not os.path.exists(f'{base}.{name}.npy'):
        sp, _ = paths(scene, spp, seed)
        o = f'{base}.{name}.exr'
        cmd = [CVTRACE, 'reconstruct', sp, '--method', method, '-o', o, '--force', '--log', 'warn', '-t', '2']
        for p in params:
            cmd += ['--param', p]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        r = read_exr(o)
        np.save(f'{base}.{name}.npy', rgb(r))
        if 'variance.R' in r:
            np.save(f'{base}.{name}_var.npy', rgb(r, 'variance.'))
        os.remove(o)
    return np.load(f'{base}.{name}.npy')
