from table import *
from filt import gblur
import sys
A=lambda d: np.clip(d['albedo'],0,1)
def tm(x): 
    y=x.mean(-1,keepdims=True); return np.clip(x/(1+y),0,1)







o=lambda d: np.maximum(d['ours'],0)
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt':lambda d:d['D_pt'],'D_ours':lambda d:d['D_ours'],
 'X_ptalbours': mk('X_ptalbours', lambda d: oidn(d['pt'], tm(o(d)), d['normal'])),
 'X_ptalbours_c': mk('X_ptalbours_c', lambda d: oidn(d['pt'], tm(o(d)), d['normal'],clean_aux=True)),
 'X_mixin': mk('X_mixin', lambda d: oidn(0.5*(d['pt']+o(d)), A(d), d['normal'])),
 'X_hp1': mk('X_hp1', lambda d: oidn(np.maximum(d['pt']-gblur(d['pt'],1)+gblur(o(d),1),0), A(d), d['normal'])),
 'X_hp2': mk('X_hp2', lambda d: oidn(np.maximum(d['pt']-gblur(d['pt'],2)+gblur(o(d),2),0), A(d), d['normal'])),
 'X_ours_is4': mk('X_ours_is4', lambda d: oidn(o(d), A(d), d['normal'], input_scale=4.0)),
 'avgD': lambda d: 0.5*(d['D_pt']+d['D_ours']),
 'avgDo': lambda d: 0.7*d['D_pt']+0.3*d['ours'],
}
evaluate(M, ['cornell-box','door-ajar','glass-of-water','glossy-room'])
