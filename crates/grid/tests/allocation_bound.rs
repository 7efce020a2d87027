//! A header that declares a huge grid in a tiny file must be refused
//! without reserving memory for the grid: every single allocation while
//! reading stays below a bound, measured by a counting global allocator
//! (this test binary only).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use surfrecon_grid::field_io::read_field;

struct Largest;

static LARGEST: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards every call to the system allocator unchanged; it only
// records the largest requested size.
unsafe impl GlobalAlloc for Largest {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static ALLOCATOR: Largest = Largest;

/// The largest single allocation while reading `text` stored as `name`,
/// and the error message.
fn largest_allocation(name: &str, text: &str) -> (usize, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    LARGEST.store(0, Ordering::Relaxed);
    let message = read_field(&path).unwrap_err().to_string();
    (LARGEST.load(Ordering::Relaxed), message)
}

#[test]
fn billion_value_headers_in_tiny_files_allocate_little() {
    // (Before the fix, the ascii data reader reserved min(count, 2^28)
    // values: 2 GiB for these files.)
    let vtk = "# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\n\
               DIMENSIONS 1000 1000 1000\nPOINT_DATA 1000000000\nSCALARS v double 1\n\
               LOOKUP_TABLE default\n1 2 3\n";
    let nrrd = "NRRD0004\ntype: double\ndimension: 3\nsizes: 1000 1000 1000\n\
                encoding: ascii\n\n1 2\n";
    let raw = "NRRD0004\ntype: double\ndimension: 3\nsizes: 1000 1000 1000\n\
               endian: little\nencoding: raw\n\n12345678";
    for (name, text) in [("big.vtk", vtk), ("big.nrrd", nrrd), ("raw.nrrd", raw)] {
        let (largest, message) = largest_allocation(name, text);
        assert!(message.contains("1000000000"), "{name}: {message}");
        assert!(
            largest < 64 * 1024,
            "{name}: one allocation of {largest} bytes"
        );
    }
}
