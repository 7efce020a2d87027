//! Digital topology on grids: the simple point test that lets a node
//! change side (inside/outside) without changing the topology of the
//! surface around it (no tunnels punched, no components split off or
//! merged), in the spirit of Han, Xu and Prince's topology-preserving
//! level sets. Level-set tagging and evolution move the surface node by
//! node with it; offset and unified fields move samples with it.

/// The 3^D − 1 neighbours of a node as linear index offsets, with their
/// adjacency as bit masks, for the simple point test of digital topology:
/// the inside is taken face-connected (6-connected in 3D, 4 in 2D), the
/// exterior fully connected (26 / 8), the pairing under which removing a
/// node with exactly one inside and one exterior component around it
/// changes no topology.
pub struct Neighbourhood {
    /// Linear index offset of each neighbour.
    offsets: Vec<isize>,
    /// Neighbours sharing a face with the centre.
    faces: u32,
    /// Neighbours with at most two nonzero offsets (N18 in 3D, N8 in 2D),
    /// where the face-connected components are counted.
    near: u32,
    /// Per neighbour: face-adjacent neighbours, fully adjacent neighbours.
    face_adjacent: Vec<u32>,
    full_adjacent: Vec<u32>,
}

impl Neighbourhood {
    pub fn new<const D: usize>(strides: &[usize; D]) -> Self {
        let cells: Vec<[i32; D]> = (0..3usize.pow(D as u32))
            .map(|k| std::array::from_fn(|a| (k / 3usize.pow(a as u32) % 3) as i32 - 1))
            .filter(|o: &[i32; D]| o.iter().any(|&c| c != 0))
            .collect();
        let nonzero = |o: &[i32; D]| o.iter().filter(|&&c| c != 0).count();
        let mask = |f: &dyn Fn(&[i32; D]) -> bool| {
            cells
                .iter()
                .enumerate()
                .filter(|(_, o)| f(o))
                .fold(0u32, |m, (i, _)| m | 1 << i)
        };
        let adjacency = |full: bool| -> Vec<u32> {
            cells
                .iter()
                .map(|u| {
                    mask(&|v: &[i32; D]| {
                        let diff: Vec<i32> = (0..D).map(|a| (u[a] - v[a]).abs()).collect();
                        let sum: i32 = diff.iter().sum();
                        sum > 0
                            && if full {
                                diff.iter().all(|&x| x <= 1)
                            } else {
                                sum == 1
                            }
                    })
                })
                .collect()
        };
        Neighbourhood {
            offsets: cells
                .iter()
                .map(|o| (0..D).map(|a| o[a] as isize * strides[a] as isize).sum())
                .collect(),
            faces: mask(&|o| nonzero(o) == 1),
            near: mask(&|o| nonzero(o) <= 2),
            face_adjacent: adjacency(false),
            full_adjacent: adjacency(true),
        }
    }

    /// Whether node `l` may change side without changing the topology:
    /// one face-connected inside component next to it and one fully
    /// connected outside component around it (`inside` tells the side of
    /// each node; the node's own side does not matter). Every neighbour of
    /// `l` must be a valid index.
    pub fn is_simple(&self, l: usize, inside: impl Fn(usize) -> bool) -> bool {
        let mut inside_mask = 0u32;
        for (i, &o) in self.offsets.iter().enumerate() {
            if inside(l.wrapping_add_signed(o)) {
                inside_mask |= 1 << i;
            }
        }
        let inside = inside_mask;
        let all = (1u32 << self.offsets.len()) - 1;
        let outside = all & !inside;
        let inside_components =
            count_components(inside & self.near, self.faces, &self.face_adjacent);
        let outside_components = count_components(outside, all, &self.full_adjacent);
        inside_components == 1 && outside_components == 1
    }
}

/// Connected components of the set `members` (bit mask) under `adjacent`
/// that contain at least one node of `seeds`.
fn count_components(members: u32, seeds: u32, adjacent: &[u32]) -> usize {
    let mut left = members;
    let mut count = 0;
    while left & seeds != 0 {
        let start = (left & seeds).trailing_zeros();
        let mut component = 1u32 << start;
        let mut frontier = component;
        while frontier != 0 {
            let i = frontier.trailing_zeros();
            frontier &= frontier - 1;
            let grow = adjacent[i as usize] & members & !component;
            component |= grow;
            frontier |= grow;
        }
        left &= !component;
        count += 1;
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 5×5×5 grid, inside = the given node coordinates.
    fn simple_in(inside: &[[usize; 3]], centre: [usize; 3]) -> bool {
        let strides = [1, 5, 25];
        let cube = Neighbourhood::new(&strides);
        let linear = |c: [usize; 3]| c[0] + 5 * c[1] + 25 * c[2];
        let set: Vec<usize> = inside.iter().map(|&c| linear(c)).collect();
        cube.is_simple(linear(centre), |n| set.contains(&n))
    }

    #[test]
    fn end_of_a_line_is_simple_but_its_middle_is_not() {
        let line = [[1, 2, 2], [2, 2, 2], [3, 2, 2]];
        assert!(simple_in(&line, [3, 2, 2]));
        // Removing the middle splits the line in two.
        assert!(!simple_in(&line, [2, 2, 2]));
    }

    #[test]
    fn filling_the_hole_of_a_ring_is_not_simple() {
        // A ring of 8 nodes around (2, 2, 2) in the plane z = 2: adding the
        // centre would close the hole (genus 1 -> 0).
        let ring: Vec<[usize; 3]> = (1..4)
            .flat_map(|x| (1..4).map(move |y| [x, y, 2]))
            .filter(|&c| c != [2, 2, 2])
            .collect();
        assert!(!simple_in(&ring, [2, 2, 2]));
        // Removing a corner breaks the face-connected loop: not simple either.
        assert!(!simple_in(&ring, [1, 1, 2]));
    }

    #[test]
    fn isolated_node_is_not_simple() {
        assert!(!simple_in(&[], [2, 2, 2]));
        // Flat side of a solid block: simple.
        let block: Vec<[usize; 3]> = (1..4)
            .flat_map(|x| (1..4).flat_map(move |y| (1..3).map(move |z| [x, y, z])))
            .collect();
        assert!(simple_in(&block, [2, 2, 2]));
    }
}
