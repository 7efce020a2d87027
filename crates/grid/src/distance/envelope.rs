//! Lower envelope of parabolas along a grid line.

/// Build in `hull` the lower envelope of the parabolas `(t - v)² + c` of
/// `count` sites given by `site(k) = (v, c, datum)` in order of `v`: (site
/// index, coordinate from which it is the lowest), ending with a sentinel
/// that starts at infinity. Of sites with the same `v`, the one with the
/// smaller `(c, datum)` stays.
pub(super) fn lower_envelope(
    count: usize,
    site: impl Fn(usize) -> (f32, f32, u32),
    hull: &mut Vec<(usize, f32)>,
) {
    hull.clear();
    for q in 0..count {
        let (v, c, datum) = site(q);
        loop {
            let Some(&(top, from)) = hull.last() else {
                hull.push((q, f32::NEG_INFINITY));
                break;
            };
            let (hv, hc, hdatum) = site(top);
            if v == hv {
                if (c, datum) < (hc, hdatum) {
                    hull.pop();
                    continue;
                }
                break;
            }
            // Where the parabolas of the top site and this one cross.
            let cross = 0.5 * (v + hv) + 0.5 * (c - hc) / (v - hv);
            if cross <= from {
                hull.pop();
            } else {
                hull.push((q, cross));
                break;
            }
        }
    }
    hull.push((usize::MAX, f32::INFINITY));
}

/// Walks the coordinates `t` of a line in increasing order and names the
/// lowest site of a [`lower_envelope`] at each.
pub(super) struct EnvelopeWalk<'a> {
    hull: &'a [(usize, f32)],
    k: usize,
}

impl<'a> EnvelopeWalk<'a> {
    pub fn new(hull: &'a [(usize, f32)]) -> Self {
        EnvelopeWalk { hull, k: 0 }
    }

    /// Index of the lowest site at `t` (finite, not below the last `t`
    /// asked). The sentinel stops the walk.
    #[inline(always)]
    pub fn lowest_at(&mut self, t: f32) -> usize {
        while self.hull[self.k + 1].1 < t {
            self.k += 1;
        }
        self.hull[self.k].0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn envelope_names_the_lowest_parabola_everywhere() {
        // Sites in order of v, with a tie at v = 2 (the lower c wins).
        let sites = [
            (0.0f32, 4.0f32, 0u32),
            (1.0, 9.0, 1),
            (2.0, 1.0, 2),
            (2.0, 0.5, 3),
            (6.0, 0.0, 4),
        ];
        let mut hull = Vec::new();
        lower_envelope(sites.len(), |k| sites[k], &mut hull);
        let mut walk = EnvelopeWalk::new(&hull);
        for step in 0..=80 {
            let t = -1.0 + step as f32 * 0.1;
            let value = |&(v, c, _): &(f32, f32, u32)| (t - v) * (t - v) + c;
            let best = sites.iter().map(value).fold(f32::INFINITY, f32::min);
            assert!(
                (value(&sites[walk.lowest_at(t)]) - best).abs() < 1e-5,
                "t = {t}"
            );
        }
        assert!(hull.iter().all(|&(k, _)| k != 1 && k != 2));
        assert_eq!(hull.last(), Some(&(usize::MAX, f32::INFINITY)));
    }
}
