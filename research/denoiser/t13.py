# oracle global linear combination (per scene+budget, fit on all 4 seeds against ref, weighted)
from table import *
names=['D_pt_ca','D_pt','X_mix0.75_ca','X_mix0.5_ca','D_ours_ca','ours','X_win4']
for b in [32,96]:
  for s in ['cornell-box','door-ajar','glass-of-water','glossy-room']:
    ref=reference(s); w=np.sqrt(weights(ref))[...,None]
    X=[];Y=[]
    for seed in SEEDS:
        c=f'{cdir(s,b)}/seed-{seed}'
        X.append(np.stack([(np.load(f'{c}.{n}.npy')*w).ravel() for n in names],1)); Y.append((ref*w).ravel())
    X=np.concatenate(X);Y=np.concatenate(Y)
    p=np.mean([relmse(np.load(f'{cdir(s,b)}/seed-{seed}.pt2n.npy'),ref) for seed in SEEDS])
    d2=np.mean([relmse(np.load(f'{cdir(s,b)}/seed-{seed}.D_pt2n.npy'),ref) for seed in SEEDS])
    for sub in [[0,5],[0,2,5],[0,2,4,5],list(range(len(names)))]:
        co,*_=np.linalg.lstsq(X[:,sub],Y,rcond=None)
        e=((X[:,sub]@co-Y)**2).mean()
        print(b,s,[names[i] for i in sub],np.round(co,3),'ratio to D_pt2n %.3f'%(e/d2))
