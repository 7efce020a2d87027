//! Lighting: a key light from the upper left, a weaker fill from the right,
//! a little ambient and a soft highlight, fixed relative to the camera so
//! every view is lit alike. Shading happens in linear light; colours are
//! given and returned in sRGB bytes.

use super::camera::Camera;
use glam::DVec3;

/// Light directions in camera coordinates (right, up, towards the viewer)
/// with their strengths.
const KEY: ([f64; 3], f64) = ([-0.55, 0.60, 0.60], 0.85);
const FILL: ([f64; 3], f64) = ([0.70, -0.15, 0.70], 0.22);
const AMBIENT: f64 = 0.07;
const SPECULAR: f64 = 0.12;
const SHININESS: i32 = 32;

/// The camera-fixed lights expressed in world coordinates.
#[derive(Clone, Debug)]
pub(crate) struct Lighting {
    key: DVec3,
    key_strength: f64,
    fill: DVec3,
    fill_strength: f64,
    /// Half-way vector between the key light and the viewer (Blinn highlight).
    half: DVec3,
}

impl Lighting {
    pub fn new(camera: &Camera) -> Lighting {
        let to_world =
            |c: [f64; 3]| (c[0] * camera.right + c[1] * camera.up + c[2] * camera.back).normalize();
        let key = to_world(KEY.0);
        Lighting {
            key,
            key_strength: KEY.1,
            fill: to_world(FILL.0),
            fill_strength: FILL.1,
            half: (key + camera.back).normalize(),
        }
    }

    /// Colour of a surface with unit normal `n` (already turned towards the
    /// viewer) and linear base colour `base`.
    pub fn shade(&self, n: DVec3, base: [f64; 3]) -> [u8; 3] {
        let diffuse = AMBIENT
            + self.key_strength * n.dot(self.key).max(0.0)
            + self.fill_strength * n.dot(self.fill).max(0.0);
        let highlight = SPECULAR * n.dot(self.half).max(0.0).powi(SHININESS);
        base.map(|c| linear_to_srgb(c * diffuse + highlight))
    }
}

/// sRGB byte to linear light in [0, 1].
pub(crate) fn srgb_to_linear(c: u8) -> f64 {
    let c = c as f64 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Entries of the linear-to-sRGB table: fine enough that every byte is
/// reproduced exactly (the steepest part of the curve moves 0.2 of a byte
/// per entry).
const SRGB_TABLE_SIZE: usize = 1 << 14;

/// Linear light (clamped to [0, 1]) to an sRGB byte, through a table: the
/// exact curve needs a `powf` per channel, which dominated rendering time.
pub(crate) fn linear_to_srgb(c: f64) -> u8 {
    static TABLE: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        (0..SRGB_TABLE_SIZE)
            .map(|i| linear_to_srgb_exact(i as f64 / (SRGB_TABLE_SIZE - 1) as f64))
            .collect()
    });
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    table[(c * (SRGB_TABLE_SIZE - 1) as f64 + 0.5) as usize]
}

/// The sRGB transfer curve itself.
fn linear_to_srgb_exact(c: f64) -> u8 {
    let s = if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// An sRGB colour as linear light.
pub(crate) fn linear(c: [u8; 3]) -> [f64; 3] {
    c.map(srgb_to_linear)
}

/// `a` moved towards `b` by `t` in [0, 1], in sRGB bytes.
pub(crate) fn mix(a: [u8; 3], b: [u8; 3], t: f64) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    [0, 1, 2].map(|i| (a[i] as f64 * (1.0 - t) + b[i] as f64 * t).round() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_every_byte() {
        for b in 0..=255u8 {
            assert_eq!(linear_to_srgb(srgb_to_linear(b)), b);
        }
    }

    #[test]
    fn surfaces_facing_the_key_light_are_brighter() {
        let camera = Camera::fit(
            &[DVec3::ZERO, DVec3::ONE],
            &[true, true],
            &super::super::RenderOptions::default(),
            100.0,
            100.0,
        );
        let light = Lighting::new(&camera);
        let lum = |c: [u8; 3]| c.iter().map(|&v| v as u32).sum::<u32>();
        let base = [0.5; 3];
        let towards = lum(light.shade(light.key, base));
        let away = lum(light.shade(-light.key, base));
        let facing_viewer = lum(light.shade(camera.back, base));
        assert!(towards > facing_viewer && facing_viewer > away);
        // Ambient keeps unlit sides from going black.
        assert!(away > 0);
    }
}
