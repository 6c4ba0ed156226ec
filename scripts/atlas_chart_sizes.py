#!/usr/bin/env python3
"""Chart sizes of a prepared atlas: how much of the texture sub-texel charts take, how much all
footprints take, and how much lies inside the boxes of hollow charts.
    python3 scripts/atlas_chart_sizes.py WORK/atlas_mesh.ply
Charts are the uv-connected components (vertices welded by position and uv; a shared block's tiny
charts count one by one); sizes in texels at 1024^2; a chart's footprint is approximated by its uv
box grown by the gutter (3 texels a side pair); all footprints together by the texels the
triangles' boxes touch, grown by one texel. Needs numpy and scipy."""
import numpy as np, sys
d=open(sys.argv[1],'rb').read()
e=d.index(b'end_header\n')+11
h=d[:e].decode().split('\n')
nv=int([l for l in h if l.startswith('element vertex')][0].split()[2]); nf=int([l for l in h if l.startswith('element face')][0].split()[2])
props=[l.split()[-1] for l in h if l.startswith('property float')]
V=np.frombuffer(d,'<f4',nv*len(props),e).reshape(nv,len(props))
fdt=[('n','u1'),('i','<i4',3)]+[(l.split()[-1],'<i4') for l in h if l.startswith('property int')]
F=np.frombuffer(d,fdt,nf,e+nv*len(props)*4)
T=F['i']; ui=props.index('s') if 's' in props else props.index('u')
UV=V[:,ui:ui+2]*1024; P=V[:,:3]
key=np.concatenate([P,UV],1)
_,w=np.unique(key,axis=0,return_inverse=True); w=w.ravel()
import scipy.sparse as sp, scipy.sparse.csgraph as cg
Tw=w[T]
g=sp.coo_matrix((np.ones(2*len(Tw)),(np.concatenate([Tw[:,0],Tw[:,1]]),np.concatenate([Tw[:,1],Tw[:,2]]))),shape=(w.max()+1,)*2)
n,lab=cg.connected_components(g,directed=False)
fl=lab[Tw[:,0]]
a=UV[T]; area=0.5*np.abs((a[:,1,0]-a[:,0,0])*(a[:,2,1]-a[:,0,1])-(a[:,1,1]-a[:,0,1])*(a[:,2,0]-a[:,0,0]))
ca=np.bincount(fl,area)
mn=np.full((n,2),1e9); mx=np.full((n,2),-1e9)
np.minimum.at(mn,fl,a.min(1)); np.maximum.at(mx,fl,a.max(1))
fp=(np.floor(mx[:,0])-np.floor(mn[:,0])+3)*(np.floor(mx[:,1])-np.floor(mn[:,1])+3)
used=ca>0
print('charts',used.sum(),'uv area (texels)',ca.sum().round())
for lim in [1,4,16]:
    s=(ca<lim)&used
    print(f' charts with < {lim} texels of area: {s.sum()}, their area {ca[s].sum():.0f} texels, alone (outside a shared block) their box footprints would take ~{fp[s].sum():.0f} texels ({fp[s].sum()/1024**2*100:.1f}% of the atlas)')
fc=np.bincount(fl)
s=(ca<1)&used
print('tiny charts with 1 face:',((fc==1)&s).sum(),' 2-10 faces:',((fc>1)&(fc<=10)&s).sum(),' >10:',((fc>10)&s).sum())
o=F[fdt[-1][0]]
objs=np.bincount(o[np.isin(fl,np.where(s)[0])])
print('objects with the most faces in sub-texel charts (id: faces):',{int(i): int(objs[i]) for i in np.argsort(-objs)[:5]})
lo=np.clip(np.floor(a.min(1)).astype(int),0,1023); hi=np.clip(np.floor(a.max(1)).astype(int),0,1023)
touched=np.zeros((1024,1024),bool)
small=(hi-lo).max(1)<8
for dy in range(8):
    for dx in range(8):
        m=small&(lo[:,0]+dx<=hi[:,0])&(lo[:,1]+dy<=hi[:,1])
        touched[lo[m,1]+dy,lo[m,0]+dx]=True
for i in np.where(~small)[0]: touched[lo[i,1]:hi[i,1]+1,lo[i,0]:hi[i,0]+1]=True
import scipy.ndimage as nd
foot=nd.binary_dilation(touched,np.ones((3,3),bool)).sum()/1024**2
box=(mx-mn).prod(1); hollow=used&(ca<0.4*box)&(box>64)
print(f'all footprints ~{foot*100:.1f}% of the atlas for {ca.sum()/1024**2*100:.1f}% of uv area; '
      f'{hollow.sum()} charts fill under 0.4 of their box, whose empty part is {(box-ca)[hollow].sum()/1024**2*100:.1f}% of the atlas')
