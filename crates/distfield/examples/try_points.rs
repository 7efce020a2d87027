//! Diagnostics (not part of the crate's API): extract a unified field with
//! some cells' feature points replaced or removed, and report how far the
//! surface lies from a reference both ways (every vertex and 16 points per
//! triangle, as `examples/sculpt_check.rs`), with the worst cells.
//! cargo run --release -p surfrecon-distfield --example try_points -- FIELD.udf REF H [SET ...]
//! SET: `i,j,k=x,y,z;i,j,k=none;i,j,k=x,y,z+x,y,z;v:i,j,k=V;...` (a cell's point,
//! none, or a first point and further points `+x,y,z+...`, kept as the
//! cell's further points ([`UnifiedField::cell_points`]); `v:` gives
//! sample i,j,k the value V spacings; changes applied together; an empty SET measures the field as it is). With
//! `TRY_OUT=PATH.ply` the last SET's surface is written there.
use std::collections::BTreeMap;
use surfrecon_distfield::extract::extract_points;
use surfrecon_distfield::features::cell_of;
use surfrecon_distfield::format::read_udf;
use surfrecon_distfield::query::{deviation, lattice_points, MeshQuery};
use surfrecon_distfield::unified::UnifiedField;
use surfrecon_geom::{io, DVec3, TriMesh};

/// Cells listed per direction.
const WORST_CELLS: usize = 6;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let field = read_udf(std::path::Path::new(&args[0])).unwrap();
    let reference = io::read(std::path::Path::new(&args[1])).unwrap().to_mesh();
    let h: f64 = args[2].parse().unwrap();
    let to_ref = MeshQuery::new(&reference).unwrap();
    let first = field.feature_points();
    let seconds = field.second_points(&first);
    let further = field.more_points();
    let sets = if args.len() > 3 {
        args[3..].to_vec()
    } else {
        vec![String::new()]
    };
    for set in &sets {
        let mut field = field.clone();
        for item in set.split(';').filter(|s| s.starts_with("v:")) {
            let (node, value) = item[2..].split_once('=').unwrap();
            let node = field.spec.linear(triple(node).map(|x| x as usize));
            field.values[node] = value.parse::<f64>().unwrap() * h;
        }
        let (mut features, mut second) = (first.clone(), seconds.clone());
        let mut more = further.clone();
        for item in set
            .split(';')
            .filter(|s| !s.is_empty() && !s.starts_with("v:"))
        {
            let (cell, point) = item.split_once('=').unwrap();
            let cell = field.spec.linear(triple(cell).map(|x| x as usize));
            second.remove(&cell);
            more.remove(&cell);
            let mut parts = point.split('+');
            match parts.next() {
                Some("none") => {
                    features.remove(&cell);
                }
                Some(a) => {
                    features.insert(cell, DVec3::from_array(triple(a)));
                }
                None => {}
            }
            let rest: Vec<DVec3> = parts.map(|b| DVec3::from_array(triple(b))).collect();
            if !rest.is_empty() {
                more.insert(cell, rest);
            }
        }
        let (out, report) = extract_points(&field, &features, &second, &more);
        if let Ok(path) = std::env::var("TRY_OUT") {
            surfrecon_geom::io::write(&path, &surfrecon_geom::Geometry::from_mesh(out.clone()))
                .unwrap();
        }
        let to_out = MeshQuery::new(&out).unwrap();
        let there = deviation(&out, &to_ref, 16);
        let back = deviation(&reference, &to_out, 16);
        println!(
            "[{set}]: fans {} refused {} merged {}; out->ref max {:.3} h at {:.3}; ref->out max {:.3} h at {:.3}",
            report.fans,
            report.fans_refused,
            report.merged,
            there.max / h,
            there.worst,
            back.max / h,
            back.worst
        );
        for (name, from, to) in [
            ("out->ref", &out, &to_ref),
            ("ref->out", &reference, &to_out),
        ] {
            println!("  {name}: {}", worst_cells(&field, from, to, h).join("; "));
        }
    }
}

fn triple(s: &str) -> [f64; 3] {
    let v: Vec<f64> = s.split(',').map(|x| x.parse().unwrap()).collect();
    [v[0], v[1], v[2]]
}

/// The cells where `from` lies farthest from `to` (16 points per
/// triangle and its corners), worst first.
fn worst_cells(field: &UnifiedField, from: &TriMesh, to: &MeshQuery, h: f64) -> Vec<String> {
    let mut by_cell: BTreeMap<usize, (f64, DVec3)> = BTreeMap::new();
    for t in 0..from.triangles.len() {
        for q in lattice_points(from.corners(t), 4).chain(from.corners(t)) {
            let d = to.signed_distance(q).abs() / h;
            if let Some(c) = cell_of(&field.spec, q) {
                let entry = by_cell.entry(c).or_insert((0.0, q));
                if d > entry.0 {
                    *entry = (d, q);
                }
            }
        }
    }
    let mut list: Vec<_> = by_cell.into_iter().collect();
    list.sort_by(|a, b| b.1 .0.total_cmp(&a.1 .0));
    list.iter()
        .take(WORST_CELLS)
        .map(|(c, (d, q))| format!("{:?} {d:.3} h at {q:.3}", field.spec.unlinear(*c)))
        .collect()
}
