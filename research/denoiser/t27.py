from table import *
from filt import gblur
import recipe
M={'D_pt2n':lambda d:d['D_pt2n'],'ours':lambda d:d['ours']}
F=lambda d: recipe.shrink(d['ours'],d['ours_var'],d['X_mix0.75_ca'])[0]
M['FINAL']=F
for s in [16,32]:
    M[f'F+lp{s}']=(lambda s: lambda d: (lambda c: c+gblur(d['ours']-c,s))(F(d)))(s)
for k in [1.0,1.5]:
    M[f'F k{k}']=(lambda k: lambda d: recipe.shrink(d['ours'],d['ours_var'],d['X_mix0.75_ca'],kappa=k)[0])(k)
res=evaluate(M, SCENES, bias=True)
