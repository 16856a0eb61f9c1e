from table import *
from blend import *
import recipe
M={'D_pt2n':lambda d:d['D_pt2n'],'ours':lambda d:d['ours'],'m75':lambda d:d['X_mix0.75_ca']}
# guided filter: guide D (m75), input ours
for r,eps in [(3,1e-4),(7,1e-4),(7,1e-2)]:
    M[f'gf{r}e{eps}']=(lambda r,eps: lambda d: guided(d['X_mix0.75_ca'].astype(np.float64), d['ours'].astype(np.float64), r, eps*np.mean(d['X_mix0.75_ca'])**2))(r,eps)
# smoothed-bias weights: b = box(o-D), w = b^2/(b^2 + box(v))
def sb(d,r,k):
    o=d['ours'];D=d['X_mix0.75_ca']; b=box((o-D).mean(-1),r); v=box(k*d['ours_var'].mean(-1),r)
    w=(b*b/np.maximum(b*b+v,1e-30))[...,None]; return D+w*(o-D)
for r in [3,7]:
    M[f'sb{r}']=(lambda r: lambda d: sb(d,r,1))(r)
# JS toward OIDN(ours)
M['js->D_ours_ca']=lambda d: recipe.shrink(d['ours'],d['ours_var'],d['D_ours_ca'])[0]
# JS with per-channel windows (recipe otherwise)
M['final_chan']=lambda d: 0.95*js(d['ours'],2*d['ours_var'],d['X_mix0.75_ca'],7,'chan')[0]+0.05*d['ours']
M['final']=lambda d: recipe.shrink(d['ours'],d['ours_var'],d['X_mix0.75_ca'])[0]
evaluate(M, SCENES)
