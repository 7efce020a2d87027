//! Diagnostics (not part of the crate's API): what a sculpted unified
//! field stores around a point, beside the field before sculpting, and how
//! far its surface there lies from a reference mesh.
//! cargo run --release -p surfrecon-distfield --example probe_sculpt -- BEFORE.udf AFTER.udf REF x,y,z [REACH]
use surfrecon_distfield::extract::corner_nodes;
use surfrecon_distfield::features::cell_of;
use surfrecon_distfield::format::read_udf;
use surfrecon_distfield::query::MeshQuery;
use surfrecon_geom::{io, DVec3};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let before = read_udf(std::path::Path::new(&args[0])).unwrap();
    let after = read_udf(std::path::Path::new(&args[1])).unwrap();
    let reference = io::read(std::path::Path::new(&args[2])).unwrap().to_mesh();
    let query = MeshQuery::new(&reference).unwrap();
    let v: Vec<f64> = args[3].split(',').map(|s| s.parse().unwrap()).collect();
    let p = DVec3::new(v[0], v[1], v[2]);
    let reach: usize = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(0);
    let spec = after.spec;
    let h = spec.spacing;
    let centre = spec.unlinear(cell_of(&spec, p).unwrap());
    let (surface, _) = after.extract();
    let points = after.feature_points();
    let old_points = before.feature_points();
    let r = reach as isize;
    for dz in -r..=r {
        for dy in -r..=r {
            for dx in -r..=r {
                let idx = [
                    (centre[0] as isize + dx) as usize,
                    (centre[1] as isize + dy) as usize,
                    (centre[2] as isize + dz) as usize,
                ];
                let c = spec.linear(idx);
                if !after.crosses(c) {
                    continue;
                }
                let lo = DVec3::from_array(spec.position(idx));
                println!("cell {idx:?} lo {lo:.4}");
                for (k, n) in corner_nodes(&spec, c).into_iter().enumerate() {
                    println!(
                        "  corner {k}: before {:+.4} h after {:+.4} h  extra before {:?} after {:?}",
                        before.values[n] / h,
                        after.values[n] / h,
                        before.extras.get(&(n as u32)),
                        after.extras.get(&(n as u32))
                    );
                }
                println!(
                    "  point before {:?} after {:?}",
                    old_points.get(&c),
                    points.get(&c)
                );
                for t in 0..surface.triangles.len() {
                    let tri = surface.corners(t);
                    let m = (tri[0] + tri[1] + tri[2]) / 3.0;
                    if cell_of(&spec, m) != Some(c) {
                        continue;
                    }
                    let worst = tri
                        .iter()
                        .chain(
                            [
                                m,
                                (tri[0] + tri[1]) * 0.5,
                                (tri[1] + tri[2]) * 0.5,
                                (tri[2] + tri[0]) * 0.5,
                            ]
                            .iter(),
                        )
                        .map(|&q| query.signed_distance(q).abs() / h)
                        .fold(0.0, f64::max);
                    println!(
                        "  tri {:.4} {:.4} {:.4}  err {worst:.3} h",
                        tri[0], tri[1], tri[2]
                    );
                }
            }
        }
    }
}
