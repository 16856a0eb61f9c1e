from table import *
from filt import box
def edges(d):
    a=d['albedo'];n=d['normal'];z=d['depth']
    H,W=z.shape
    E=np.zeros((H,W))
    zp=np.pad(z,1,mode='edge');ap=np.pad(a,((1,1),(1,1),(0,0)),mode='edge');npd=np.pad(n,((1,1),(1,1),(0,0)),mode='edge')
    for dy in (-1,0,1):
        for dx in (-1,0,1):
            sl=(slice(1+dy,1+dy+H),slice(1+dx,1+dx+W))
            E=np.maximum(E, np.abs(ap[sl]-a).max(-1)+np.abs(npd[sl]-n).max(-1)+np.abs(zp[sl]-z)/np.maximum(z,1e-3))
    return E
for s in ['cornell-box','door-ajar','glass-of-water','glossy-room']:
  for b in [32,96]:
    ref=reference(s); w=weights(ref)
    acc=[]
    for seed in SEEDS:
        d=data(s,b,seed); E=edges(d)
        row=[]
        for th in [0.05,0.2]:
            m=E>th
            eD=(((d['D_pt_ca']-ref)**2).mean(-1)*w); eo=(((d['ours']-ref)**2).mean(-1)*w)
            row+= [m.mean(), eD[m].sum()/eD.size, eo[m].sum()/eD.size, eD.mean()]
        acc.append(row)
    a=np.mean(acc,0)
    print(s,b,' | '.join('frac %.3f D_edge %.2e ours_edge %.2e D_tot %.2e'%tuple(a[4*i:4*i+4]) for i in range(2)))
