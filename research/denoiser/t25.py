# check recipe.shrink == blend.js path; raw-aux variant of the mix
from table import *
from blend import js
import recipe
d=data('engine',32,0)
a=recipe.shrink(d['ours'],d['ours_var'],d['X_mix0.75_ca'])[0]
b=0.95*js(d['ours'],2*d['ours_var'],d['X_mix0.75_ca'],7,'lum')[0]+0.05*d['ours']
print('max diff',np.abs(a-b).max())
A=lambda d: np.clip(d['albedo'],0,1)
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt2n_ca':lambda d:d['D_pt2n_ca'],'ours':lambda d:d['ours'],
   'm75raw':mk('X_mix0.75_raw',lambda d: oidn(recipe.denoiser_input(d['pt'],d['ours']),A(d),d['normal'])),
   'm75':lambda d:d['X_mix0.75_ca']}
M['final']=lambda d: recipe.shrink(d['ours'],d['ours_var'],d['X_mix0.75_ca'])[0]
M['final_raw']=lambda d: recipe.shrink(d['ours'],d['ours_var'],M['m75raw'](d))[0]
evaluate(M, SCENES)
