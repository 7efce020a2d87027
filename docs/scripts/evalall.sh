#!/bin/bash
# evalall.sh BIN OUTDIR [reconstruct flags]: every harness input, our eval; prints a table and writes OUTDIR/table.tsv
B=$1; O=$2; shift 2; mkdir -p $O; R=${HARNESS:-/work/runs/h11}  # harness inputs: <shape>/inputs/<variant>.ply and gt/<shape>.ply
SHAPES=${SHAPES:-"box bun_zipper fandisk sphere spikes torus two_torus"}
VARIANTS=${VARIANTS:-"clean clean_nonormals noise_0.25pct noise_1pct outliers_5pct nonuniform holes slices"}
for s in $SHAPES; do
  gt=$R/gt/$s.ply; [ $s = fandisk ] && gt=${SHARED:-../shared}/data/fandisk/fandisk.off
  for v in $VARIANTS; do
    in=$R/$s/inputs/$v.ply; out=$O/${s}_$v.ply
    /usr/bin/time -f "%e %U %M" -o $O/${s}_$v.time $B reconstruct $in -o $out --quiet "$@" 2>$O/${s}_$v.err || { echo -e "$s\t$v\tFAILED"; continue; }
    $B eval $out -r $gt --data $in --json > $O/${s}_$v.eval 2>/dev/null
    python3 - $O $s $v <<'PY'
import json,sys
o,s,v=sys.argv[1:4]; e=json.load(open(f"{o}/{s}_{v}.eval")); t=open(f"{o}/{s}_{v}.time").read().split()
d=e.get('data_fit',{})
row=[s,v,f"{1000*e['chamfer_l1']/e['diagonal']:.3f}",f"{e['fscore_1pct']:.4f}",str(e['components']),str(e['euler']),str(e['watertight']),f"{100*d.get('max',0):.2f}",f"{d.get('within_0_25pct',0):.4f}",t[0],t[1],str(int(t[2])//1024)]
print("\t".join(row)); open(f"{o}/table.tsv","a").write("\t".join(row)+"\n")
PY
  done
done
