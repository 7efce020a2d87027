//! File reading throughput: 1M points with normals as binary PLY (float and
//! double), ascii PLY and XYZ; also writing. Run with
//! `cargo bench -p surfrecon-geom --bench io`. Prints best-of-N wall times
//! from a warm page cache and points per second.

use std::path::Path;
use std::time::Instant;
use surfrecon_geom::io::{self, Encoding, Format, WriteOptions};
use surfrecon_geom::{DVec3, Geometry, PointCloud};

const POINTS: usize = 1_000_000;

/// Points on a unit sphere with outward normals, from a fixed sequence.
fn cloud(n: usize) -> Geometry {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let positions: Vec<DVec3> = (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            DVec3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect();
    let normals = positions.clone();
    Geometry::from_points(PointCloud {
        positions,
        normals: Some(normals),
        scalars: None,
    })
}

/// The usual scanner layout: six 32-bit floats per vertex.
fn write_float_ply(path: &Path, g: &Geometry) {
    let pts = &g.points;
    io::write_atomic(path, |w| {
        write!(
            w,
            "ply\nformat binary_little_endian 1.0\nelement vertex {}\n\
             property float x\nproperty float y\nproperty float z\n\
             property float nx\nproperty float ny\nproperty float nz\nend_header\n",
            pts.len()
        )?;
        let normals = pts.normals.as_ref().expect("normals");
        for (p, n) in pts.positions.iter().zip(normals) {
            for v in p.to_array().into_iter().chain(n.to_array()) {
                w.write_all(&(v as f32).to_le_bytes())?;
            }
        }
        Ok(())
    })
    .expect("write float ply");
}

/// Best of `runs` wall times, in seconds.
fn best_of(runs: usize, mut f: impl FnMut()) -> f64 {
    (0..runs)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// CPU seconds (user + system, all threads) the process spends in `f`;
/// unlike wall time, this hardly depends on other load on the machine.
/// Linux only (`/proc/self/stat`); NaN elsewhere.
fn cpu_seconds(f: impl FnOnce()) -> f64 {
    fn ticks() -> Option<f64> {
        let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
        // Fields after the parenthesised command name; utime and stime are
        // the 14th and 15th fields of the whole line.
        let rest = stat.rsplit_once(')')?.1;
        let fields: Vec<&str> = rest.split_whitespace().collect();
        let user: f64 = fields.get(11)?.parse().ok()?;
        let system: f64 = fields.get(12)?.parse().ok()?;
        Some(user + system)
    }
    const TICKS_PER_SECOND: f64 = 100.0;
    let before = ticks();
    f();
    match (before, ticks()) {
        (Some(a), Some(b)) => (b - a) / TICKS_PER_SECOND,
        _ => f64::NAN,
    }
}

/// Best wall time of `runs` reads; also prints the mean CPU time per read
/// (all threads), the fairer figure on a shared, loaded machine.
fn time_read(label: &str, path: &Path, runs: usize) -> (f64, f64) {
    let _ = std::fs::read(path); // warm the page cache
    let mut count = 0;
    let mut t = f64::INFINITY;
    let cpu = cpu_seconds(|| {
        t = best_of(runs, || {
            let g = io::read(path).expect("read");
            count = g.points.len();
        })
    }) / runs as f64;
    let mb = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0) as f64 / 1e6;
    println!(
        "read  {label:<31} {count} pts {mb:6.1} MB  wall {t:7.4} s  cpu {cpu:7.4} s  \
         {:5.1} Mpts/s  {:5.0} MB/s",
        count as f64 / t / 1e6,
        mb / t
    );
    (t, cpu)
}

fn time_write(label: &str, path: &Path, g: &Geometry, format: Format, encoding: Encoding) {
    let t = best_of(3, || {
        io::write_as(path, g, format, WriteOptions { encoding }).expect("write")
    });
    println!(
        "write {label:<28} {} pts  {:8.4} s  {:6.1} Mpts/s",
        g.points.len(),
        t,
        g.points.len() as f64 / t / 1e6
    );
}

fn main() {
    let dir = tempfile::tempdir().expect("temp dir");
    let g = cloud(POINTS);
    let float_ply = dir.path().join("float_le.ply");
    let double_ply = dir.path().join("double_le.ply");
    let double_be = dir.path().join("double_be.ply");
    let ascii_ply = dir.path().join("ascii.ply");
    let xyz = dir.path().join("points.xyz");
    write_float_ply(&float_ply, &g);
    time_write(
        "binary PLY (double, LE)",
        &double_ply,
        &g,
        Format::Ply,
        Encoding::BinaryLittleEndian,
    );
    time_write(
        "binary PLY (double, BE)",
        &double_be,
        &g,
        Format::Ply,
        Encoding::BinaryBigEndian,
    );
    time_write("ascii PLY", &ascii_ply, &g, Format::Ply, Encoding::Ascii);
    time_write("XYZ", &xyz, &g, Format::Xyz, Encoding::Ascii);
    println!();
    let float = time_read("binary PLY float LE + normals", &float_ply, 7);
    time_read("binary PLY double LE + normals", &double_ply, 7);
    time_read("binary PLY double BE + normals", &double_be, 7);
    let ascii = time_read("ascii PLY + normals", &ascii_ply, 3);
    let text = time_read("XYZ + normals", &xyz, 3);
    let bytes = std::fs::read(&float_ply).expect("read");
    let t_fs = best_of(7, || {
        std::hint::black_box(std::fs::read(&float_ply).expect("read"));
    });
    let t_parse = best_of(7, || {
        std::hint::black_box(io::read_bytes(&bytes, Format::Ply, "mem").expect("parse"));
    });
    println!("binary PLY float: file to memory {t_fs:.4} s, parsing {t_parse:.4} s");
    println!();
    println!(
        "ascii PLY / binary float PLY read: wall {:.1}x, cpu {:.1}x",
        ascii.0 / float.0,
        ascii.1 / float.1
    );
    println!(
        "XYZ / binary float PLY read:       wall {:.1}x, cpu {:.1}x",
        text.0 / float.0,
        text.1 / float.1
    );
    let verdict = |t: f64| if t < 0.1 { "met" } else { "NOT met" };
    println!(
        "target: 1M-point binary PLY with normals < 0.1 s warm: wall {} ({:.4} s), cpu {} ({:.4} s)",
        verdict(float.0),
        float.0,
        verdict(float.1),
        float.1
    );
    println!(
        "machine: {} hardware threads; load average now {}",
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
}
