from table import *
from blend import *
import sys
sc=sys.argv[1].split(',') if len(sys.argv)>1 else None
def Dm(d): return 0.5*(d['D_pt_ca']+d['X_mix0.75_ca'])
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt2n_ca':lambda d:d['D_pt2n_ca'],'ours':lambda d:d['ours'],'D_pt_ca':lambda d:d['D_pt_ca'],
   'mix75':lambda d:d['X_mix0.75_ca'],'Davg':Dm,
   'Davg+.15o':lambda d:0.85*Dm(d)+0.15*d['ours'],
   'js7k2(Davg)':lambda d: js(d['ours'],2*d['ours_var'],Dm(d),7,'lum')[0],
   'js7k2+.1o':lambda d: 0.9*js(d['ours'],2*d['ours_var'],Dm(d),7,'lum')[0]+0.1*d['ours'],
   'lp8(Davg)':lambda d: lowres(d['ours'],Dm(d),8),
}
evaluate(M, sc, bias=True)
