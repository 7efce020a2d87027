//! `write_atomic`, `write` and `read` on real files.

use super::*;
use crate::io::{read, write, write_atomic};

fn entries(dir: &std::path::Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn failed_write_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.ply");
    let result = write_atomic(&path, |w| {
        w.write_all(b"partial")?;
        Err(std::io::Error::other("boom"))
    });
    assert!(result.is_err());
    assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
}

#[test]
fn failed_write_keeps_the_old_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.txt");
    std::fs::write(&path, b"old").unwrap();
    let _ = write_atomic(&path, |_| Err(std::io::Error::other("boom")));
    assert_eq!(std::fs::read(&path).unwrap(), b"old");
    write_atomic(&path, |w| w.write_all(b"new")).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"new");
    assert_eq!(entries(dir.path()), vec!["out.txt".to_string()]);
}

#[test]
fn write_then_read_by_extension() {
    let dir = tempfile::tempdir().unwrap();
    let g = sample_mesh();
    for name in ["a.ply", "b.OBJ", "c.off", "d.xyz", "e.stl"] {
        let path = dir.path().join(name);
        write(&path, &g).unwrap();
        let back = read(&path).unwrap();
        assert_eq!(back.points.len(), g.points.len(), "{name}");
    }
}

#[test]
fn refused_geometry_creates_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("points.stl");
    let g = Geometry::from_points(crate::PointCloud::new(vec![DVec3::ZERO]));
    assert!(write(&path, &g).is_err());
    assert!(entries(dir.path()).is_empty());
}

#[test]
fn missing_files_and_unknown_extensions_are_errors() {
    let err = read("/nonexistent/dir/x.ply").unwrap_err();
    assert!(matches!(err, GeomError::Io { .. }));
    assert!(err.to_string().contains("/nonexistent/dir/x.ply"), "{err}");
    let err = read("cloud.pcd").unwrap_err();
    assert!(err.to_string().contains("unknown file format"), "{err}");
}

#[cfg(unix)]
#[test]
fn outputs_get_ordinary_file_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("plain.txt");
    std::fs::write(&plain, b"x").unwrap(); // 0666 less the umask
    let written = dir.path().join("written.txt");
    write_atomic(&written, |w| w.write_all(b"x")).unwrap();
    let mode = |p: &std::path::Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode(&written), mode(&plain) & 0o644);
}
