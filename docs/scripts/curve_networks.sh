#!/bin/bash
# curve_networks.sh BIN OUTDIR [reconstruct flags]: the curve-network table rows (VIPSS torus samples from ../shared; bunny/fandisk section networks from docs/scripts/section_network.py in $SECTIONS,
# made there when missing with $PY, a python that has numpy and open3d, e.g. the bench harness's venv; default OUTDIR/sections)
B=$1; O=$2; shift 2; mkdir -p $O; V=${SHARED:-../shared}/data/small/vipss
SECTIONS=${SECTIONS:-$O/sections}; mkdir -p $SECTIONS
here=$(dirname "$0")
[ -f $SECTIONS/bunny15.obj ] || ${PY:-python3} $here/section_network.py ${SHARED:-../shared}/data/stanford_bunny/reconstruction/bun_zipper.ply $SECTIONS/bunny15
[ -f $SECTIONS/fandisk15.obj ] || ${PY:-python3} $here/section_network.py ${SHARED:-../shared}/data/fandisk/fandisk.off $SECTIONS/fandisk15
run() { name=$1 in=$2 gt=$3; shift 3
  /usr/bin/time -f "%e %M" -o $O/$name.time $B reconstruct $in -o $O/$name.ply --json "$@" > $O/$name.json 2>$O/$name.err || { echo "$name FAILED"; cat $O/$name.err; return; }
  $B eval $O/$name.ply -r $gt --data $in --json > $O/$name.eval 2>/dev/null
  python3 - $O $name <<'PY'
import json,sys
o,n=sys.argv[1:3]; e=json.load(open(f"{o}/{n}.eval")); r=json.load(open(f"{o}/{n}.json")); t=open(f"{o}/{n}.time").read().split()
df=e.get('data_fit') or {}
g=(2-e['euler'])//2 if e['components']==1 else None
print(f"{n:12s} CD {1000*e['chamfer_l1']/e['diagonal']:.3f} F {e['fscore_1pct']:.4f} comp {e['components']} euler {e['euler']} wt {e['watertight']} data_max {100*df.get('max',0):.3f}%diag within0.5 {df.get('within_0_5pct')} {t[0]}s {int(t[1])//1024}MB method {r.get('method')} {r.get('curve_network',{}).get('samples') if isinstance(r.get('curve_network'),dict) else ''}")
PY
}
run crosscut $V/torus_crosscut.xyz $V/torus_gt.obj "$@"
run wires $V/torus_wires.xyz $V/torus_gt.obj "$@"
run parallelcut $V/torus_parallelcut.xyz $V/torus_gt.obj "$@"
run bunny15 $SECTIONS/bunny15.obj ${SHARED:-../shared}/data/stanford_bunny/reconstruction/bun_zipper.ply "$@"
run fandisk15 $SECTIONS/fandisk15.obj ${SHARED:-../shared}/data/fandisk/fandisk.off "$@"
