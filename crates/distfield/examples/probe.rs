//! Diagnostics (not part of the crate's API): what the unified field of a
//! mesh stores around given points.
//! cargo run --release -p surfrecon-distfield --example probe -- MESH CELLS x,y,z ...
use surfrecon_distfield::features::{cell_of, cells_with_features, Features};
use surfrecon_distfield::unified::{build_udf, Extra, UdfOptions};
use surfrecon_geom::{io, DVec3};
use surfrecon_grid::GridSize;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mesh = io::read(std::path::Path::new(&args[0])).unwrap().to_mesh();
    let cells: usize = args[1].parse().unwrap();
    let options = UdfOptions {
        size: GridSize::Resolution(cells),
        ..Default::default()
    };
    let (field, _) = build_udf(&mesh, &options).unwrap();
    let spec = field.spec;
    let h = spec.spacing;
    let features = Features::detect(&mesh, 30.0);
    let fcells = cells_with_features(&mesh, &features, &spec, |c| field.crosses(c));
    let points = field.feature_points();
    let (out, _) = field.extract();
    let near_tris = |m: &surfrecon_geom::TriMesh, p: DVec3, r: f64| {
        let mut normals: Vec<(DVec3, f64)> = Vec::new();
        for t in 0..m.triangles.len() {
            let [a, b, c] = m.corners(t);
            let q = surfrecon_geom::metrics::closest_point_on_triangle(p, [a, b, c]);
            if q.distance(p) < r {
                let n = (b - a).cross(c - a);
                let area = n.length();
                let n = n / area;
                if let Some(e) = normals.iter_mut().find(|e| e.0.dot(n) > 0.999) {
                    e.1 += area;
                } else {
                    normals.push((n, area));
                }
            }
        }
        normals
    };
    let crop = |m: &surfrecon_geom::TriMesh, p: DVec3, r: f64| {
        let triangles = (0..m.triangles.len())
            .filter(|&t| {
                let [a, b, c] = m.corners(t);
                ((a + b + c) / 3.0 - p).abs().max_element() < r
            })
            .map(|t| m.triangles[t])
            .collect();
        surfrecon_geom::TriMesh {
            vertices: m.vertices.clone(),
            triangles,
            normals: None,
        }
    };
    for (k, a) in args[2..].iter().enumerate() {
        let v: Vec<f64> = a.split(',').map(|s| s.parse().unwrap()).collect();
        let p = DVec3::new(v[0], v[1], v[2]);
        let g = spec.to_grid(p.to_array());
        println!("== {p} grid {:.2},{:.2},{:.2}", g[0], g[1], g[2]);
        for (name, m) in [("mesh", &mesh), ("out", &out)] {
            let ns = near_tris(m, p, 0.5 * h);
            let txt: Vec<String> = ns
                .iter()
                .map(|(n, a)| format!("({:.2},{:.2},{:.2})x{:.3}", n.x, n.y, n.z, a / (h * h)))
                .collect();
            println!("  {name} normals within h/2: {}", txt.join(" "));
        }
        if std::env::var_os("CROP").is_some() {
            for (name, m) in [("mesh", &mesh), ("out", &out)] {
                let path = format!("/tmp/probe_{k}_{name}.ply");
                let g = surfrecon_geom::Geometry::from_mesh(crop(m, p, 2.0 * h));
                io::write(std::path::Path::new(&path), &g).unwrap();
            }
        }
        if std::env::var_os("TRIS").is_some() {
            let fps: Vec<DVec3> = points.values().copied().collect();
            let o = DVec3::from_array(spec.position([0, 0, 0]));
            let g = |v: DVec3| {
                let q = (v - o) / h;
                let f = if fps.iter().any(|&f| f.distance(v) < 1e-12) {
                    "F"
                } else {
                    ""
                };
                format!("({:.2},{:.2},{:.2}){f}", q.x, q.y, q.z)
            };
            let c = crop(&out, p, 1.0 * h);
            let exact = surfrecon_distfield::query::MeshQuery::new(&mesh).unwrap();
            for t in &c.triangles {
                let [a, b, cc] = t.map(|i| c.vertices[i as usize]);
                let m = (a + b + cc) / 3.0;
                println!(
                    "   tri {} {} {}  centroid err {:.3}",
                    g(a),
                    g(b),
                    g(cc),
                    exact.signed_distance(m) / h
                );
            }
        }
        let c0 = cell_of(&spec, p).unwrap();
        let i0 = spec.unlinear(c0);
        for dk in -1i64..=1 {
            for dj in -1i64..=1 {
                for di in -1i64..=1 {
                    let idx = [i0[0] as i64 + di, i0[1] as i64 + dj, i0[2] as i64 + dk];
                    let idx = idx.map(|x| x as usize);
                    let c = spec.linear(idx);
                    let lo = DVec3::from_array(spec.position(idx));
                    let f = fcells.get(&c);
                    let fp = points.get(&c);
                    if f.is_none() && fp.is_none() {
                        continue;
                    }
                    let mark = if c == c0 { "*" } else { " " };
                    print!("{mark}cell {:?} crosses {}", idx, field.crosses(c));
                    if let Some(f) = f {
                        print!(
                            " corners {} near {} bends {} pieces {} lines {}",
                            f.corners.len(),
                            f.near_corners.len(),
                            f.bends.len(),
                            f.pieces.len(),
                            f.lines()
                        );
                    }
                    if let Some(q) = fp {
                        let l = (*q - lo) / h;
                        print!(" point ({:.2},{:.2},{:.2})", l.x, l.y, l.z);
                    }
                    println!();
                    if let Some(f) = f {
                        for &[a, b] in &f.pieces {
                            let (a, b) = ((a - lo) / h, (b - lo) / h);
                            println!(
                                "     piece ({:.2},{:.2},{:.2})-({:.2},{:.2},{:.2})",
                                a.x, a.y, a.z, b.x, b.y, b.z
                            );
                        }
                        for &q in f.corners.iter().chain(&f.near_corners) {
                            let l = (q - lo) / h;
                            println!("     corner ({:.2},{:.2},{:.2})", l.x, l.y, l.z);
                        }
                    }
                }
            }
        }
        let corners = (0..8).map(|c| {
            let idx = [i0[0] + (c & 1), i0[1] + ((c >> 1) & 1), i0[2] + (c >> 2)];
            let n = spec.linear(idx);
            let tag = match field.extras.get(&(n as u32)) {
                None => "",
                Some(Extra::Directed(_)) => "D",
                Some(Extra::FeaturePoint(_)) => "F",
                Some(Extra::Position(_)) => "P",
            };
            format!("{:.2}{}", field.values[n] / h, tag)
        });
        println!("  values {:?}", corners.collect::<Vec<_>>());
    }
}
