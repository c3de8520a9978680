"""Writes a mesh as the peer probe reads it: u32 triangle count, 13 f32 (camera from, at,
up, vertical angle in degrees, light), then 9 f32 per triangle. `to_bin.py dragon PLY.GZ OUT`
reads the Stanford dragon (ASCII PLY) and frames it; `to_bin.py nff NFF OUT` reads an NFF's
polygons, view and first light."""
import gzip, struct, sys
def write(path, tris, cam, light):
    with open(path,'wb') as f:
        f.write(struct.pack('<I', len(tris)))
        f.write(struct.pack('<13f', *cam, *light))  # from(3) at(3) up(3) fov(1) light(3)
        for t in tris: f.write(struct.pack('<9f', *t))
def dragon(src, dst):
    lines = gzip.open(src,'rt').read().split('\n')
    i = lines.index('end_header')+1
    head = {l.split()[1]: int(l.split()[2]) for l in lines[:i] if l.startswith('element')}
    nv, nf = head['vertex'], head['face']
    vs = [tuple(map(float, l.split()[:3])) for l in lines[i:i+nv]]
    tris=[]
    for l in lines[i+nv:i+nv+nf]:
        p=l.split(); n=int(p[0]); idx=list(map(int,p[1:1+n]))
        for k in range(1,n-1): tris.append(vs[idx[0]]+vs[idx[k]]+vs[idx[k+1]])
    mn=[min(v[a] for v in vs) for a in range(3)]; mx=[max(v[a] for v in vs) for a in range(3)]
    c=[(mn[a]+mx[a])/2 for a in range(3)]; s=max(mx[a]-mn[a] for a in range(3))
    cam=(c[0]+0.3*s, c[1]+0.25*s, c[2]+1.1*s, *c, 0,1,0, 45.0)
    light=(c[0]-s, c[1]+2*s, c[2]+s)
    write(dst, tris, cam, light)
def nff(src, dst):
    L=open(src).read().split('\n'); i=0; tris=[]; cam={}; light=None
    while i < len(L):
        p=L[i].split()
        if not p: i+=1; continue
        if p[0] in ('from','at','up'): cam[p[0]]=tuple(map(float,p[1:4]))
        elif p[0]=='angle': cam['angle']=float(p[1])
        elif p[0]=='l' and light is None: light=tuple(map(float,p[1:4]))
        elif p[0]=='p':
            n=int(p[1]); v=[tuple(map(float,L[i+1+k].split()[:3])) for k in range(n)]
            for k in range(1,n-1): tris.append(v[0]+v[k]+v[k+1])
            i+=n
        i+=1
    write(dst, tris, (*cam['from'],*cam['at'],*cam['up'],cam['angle']), light)
if sys.argv[1] == 'dragon':
    dragon(sys.argv[2], sys.argv[3])
else:
    nff(sys.argv[2], sys.argv[3])
