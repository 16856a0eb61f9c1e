from table import *
from blend import box
import recipe
def sh(d,k,g,r=7,om=0.05):
    o=d['ours'].astype(np.float64);D=d['X_mix0.75_ca'].astype(np.float64);e=o-D
    se=box((e*e).mean(-1),r); sv=box(k*d['ours_var'].mean(-1)+g*d['var_pt'].mean(-1),r)
    w=np.clip(np.where(se>0,1-sv/np.maximum(se,1e-30),0),0,1)[...,None]
    return (1-om)*(D+w*e)+om*o
M={'D_pt2n':lambda d:d['D_pt2n'],'ours':lambda d:d['ours'],'FINAL':lambda d: recipe.shrink(d['ours'],d['ours_var'],d['X_mix0.75_ca'])[0]}
for k,g in [(2,0.003),(2,0.01),(1.5,0.01),(1,0.03)]:
    M[f'k{k}g{g}']=(lambda k,g: lambda d: sh(d,k,g))(k,g)
evaluate(M, SCENES)
