import time, numpy as np
from common import *
from table import data
import recipe
d=data('sponza',32,0)
def up(x): return np.ascontiguousarray(np.tile(np.kron(x, np.ones((6,6,1),np.float32)) if x.ndim==3 else x,(1,1,1))[:1080,:1920])
big={k:up(d[k]) for k in ['pt','ours','ours_var','albedo','normal']}
for name,(img) in [('320x180',d),('1920x1080',big)]:
    t=time.perf_counter(); A,N=prefilter_aux(img['albedo'],img['normal']); t1=time.perf_counter()
    D=oidn(recipe.denoiser_input(img['pt'],img['ours']),A,N,clean_aux=True); t2=time.perf_counter()
    C=recipe.shrink(img['ours'],img['ours_var'],D)[0]; t3=time.perf_counter()
    print(name,'aux prefilter (2 OIDN runs) %.2fs, main OIDN %.2fs, shrink (numpy) %.2fs'%(t1-t,t2-t1,t3-t2))
