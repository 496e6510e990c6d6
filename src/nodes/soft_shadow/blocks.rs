//! Which blocks of the grid's directions a build covers: those whose cells a penumbra cone may
//! reach (seen from the light, each cone's cap bounded in each layer's projection), every
//! block where that cannot be bounded.

use crate::nodes::groups::shadow::{SoftLight, MAX_SOFT_SPHERES};

/// Per layer, a rectangle of blocks of 2 × 2 directions (indexed by their anchor, the
/// direction at even indices), `[x0, y0, x1, y1]` from `(x0, y0)` to `(x1, y1)` exclusive;
/// empty where `x1 <= x0` or `y1 <= y0`.
pub(super) type Blocks = [[u32; 4]; 6];

/// The relative margin on the sine of a penumbra cone's half-angle: `PENUMBRA_CONE_MARGIN` of
/// `shaders/shared/pcss.wgsl` (a unit test holds them equal).
const PENUMBRA_CONE_MARGIN: f64 = 1.10;

/// Every block of a grid of `n`² directions, in each of `layers` layers.
pub(super) fn every_block(n: u32, layers: usize) -> Blocks {
    let a = n.div_ceil(2);
    std::array::from_fn(|i| if i < layers { [0, 0, a, a] } else { [0; 4] })
}

/// The blocks of each layer a build must cover: those with a direction within two cells of
/// one that meets a penumbra cone (`may_be_hidden` in `shaders/shared/pcss.wgsl`; a rest
/// direction's anchor neighbours lie one cell away). Outside them every cell is lit, as the whole
/// build
/// would leave it: a cell outside every cone is lit, and so is the mean of lit neighbours.
///
/// Seen from the light, every point of the cone of occluder sphere `(c, ρ)` lies within the
/// cone's half-angle `θ` (`sin θ = margin · (radius + ρ) / |c − light|`) of its axis: the
/// cone's apex lies on the axis between the light and `c`. A layer's projection centred on
/// the light maps a direction `d` to `x = (X·d) / (W·d)` (`X`, `W` rows of `clip_from_world`),
/// monotonic in the azimuth of `d` around the axis normal to `W` and `X`, and the azimuths of a
/// spherical cap not around that axis span `±asin(sin θ / sin η)` (`η` the cap's angle from
/// it). `x` and `y` over the cap bound its cells. Layers whose projection is not centred on
/// the light (to within a fraction of a cell), and cones around it, take every block.
pub(crate) fn penumbra_blocks(
    faces: &[glam::Mat4],
    light: glam::Vec3,
    radius: f32,
    soft: SoftLight,
    spheres: &[[f32; 4]; MAX_SOFT_SPHERES],
    n: u32,
) -> Blocks {
    use glam::DVec3;
    let every = every_block(n, faces.len());
    let count = soft.spheres as usize;
    if count == 0 {
        return every; // no bounds: every cell is estimated
    }
    let light = light.as_dvec3();
    // The cones' axes and half-angles; any around the light covers everything.
    let mut cones = Vec::with_capacity(count);
    for sphere in &spheres[..count.min(MAX_SOFT_SPHERES)] {
        let to_c = DVec3::new(sphere[0].into(), sphere[1].into(), sphere[2].into()) - light;
        let l = to_c.length();
        // 1% beyond the shaders' margin: their f32 arithmetic against this f64.
        let sin_t =
            1.01 * PENUMBRA_CONE_MARGIN * (f64::from(radius) + f64::from(sphere[3])) / l.max(1e-30);
        if sin_t.is_nan() || sin_t >= 0.99 {
            return every;
        }
        cones.push((to_c / l, sin_t.asin()));
    }
    let a = i64::from(n.div_ceil(2));
    let cells = f64::from(n);
    // The grid's least distance, as the shaders take it.
    let nearest = f64::from(soft.near(radius));
    let mut blocks = [[0; 4]; 6];
    for (layer, face) in faces.iter().enumerate() {
        let m = face.as_dmat4();
        // Centred: the light projects to x = y = w = 0, to within a fifth of a cell's NDC
        // for a point at the grid's least distance up to 87° off the layer's axis (in f32 a
        // light far from the origin with occluders close to it is not).
        let centre = m * light.extend(1.0);
        let off = centre.x.abs().max(centre.y.abs()).max(centre.w.abs());
        let centred = off <= 0.01 / cells * m.row(3).truncate().length() * nearest;
        if !centred {
            blocks[layer] = every[layer];
            continue;
        }
        // The union of the cones' boxes, in NDC.
        let ndc = cones
            .iter()
            .filter_map(|&(axis, theta)| cap_ndc(&m, axis, theta))
            .reduce(|u, b| {
                [
                    u[0].min(b[0]),
                    u[1].max(b[1]),
                    u[2].min(b[2]),
                    u[3].max(b[3]),
                ]
            });
        let Some([x0, x1, y0, y1]) = ndc else {
            continue; // no cone reaches this layer: all lit
        };
        // Cell c's centre lies at NDC x = 2 (c + ½) / n − 1, y = 1 − 2 (c + ½) / n; one cell
        // for rounding, two for the neighbours, then the blocks holding them.
        let cell = |t: f64| t * cells - 0.5;
        let lo = |t: f64| (cell(t).floor() as i64 - 3).clamp(0, 2 * a - 1) / 2;
        let hi = |t: f64| ((cell(t).ceil() as i64 + 3).clamp(0, 2 * a - 1) / 2 + 1).min(a);
        let (u0, u1) = ((x0 + 1.0) / 2.0, (x1 + 1.0) / 2.0);
        let (v0, v1) = ((1.0 - y1) / 2.0, (1.0 - y0) / 2.0);
        blocks[layer] = [lo(u0), lo(v0), hi(u1), hi(v1)].map(|b| b as u32);
    }
    blocks
}

/// The NDC box `[x0, x1, y0, y1]` (within [−1, 1]) of the directions within `theta` of the
/// unit `axis` that a layer's `clip_from_world` centred on the light projects in front of it
/// (see [`penumbra_blocks`]); None where they miss the layer.
fn cap_ndc(face: &glam::DMat4, axis: glam::DVec3, theta: f64) -> Option<[f64; 4]> {
    use std::f64::consts::{FRAC_PI_2, PI};
    let w = face.row(3).truncate();
    // The range of (row·d) / (w·d): d at azimuth ψ (from w's direction f towards the part r
    // of `row` across it) gives (α + ρ tan ψ) / |w|, increasing in ψ ∈ (−π/2, π/2).
    let range = |row: glam::DVec3| -> Option<(f64, f64)> {
        let w_len = w.length();
        let f = w / w_len;
        let alpha = row.dot(f);
        let across = row - alpha * f;
        let rho = across.length();
        if !(rho > 1e-9 * row.length() && w_len > 0.0) {
            return Some((-1.0, 1.0));
        }
        let r = across / rho;
        let eta = axis.dot(f.cross(r)).clamp(-1.0, 1.0).acos();
        let (lo, hi) = if eta <= theta || eta >= PI - theta {
            (-FRAC_PI_2, FRAC_PI_2) // the cap holds the pole: every azimuth
        } else {
            let spread = (theta.sin() / eta.sin()).min(1.0).asin();
            let centre = axis.dot(r).atan2(axis.dot(f));
            // Azimuths beyond ±π wrap into (−π, −π/2) or (π/2, π): behind the layer.
            (
                (centre - spread).max(-FRAC_PI_2),
                (centre + spread).min(FRAC_PI_2),
            )
        };
        if lo >= hi {
            return None;
        }
        let edge = FRAC_PI_2 - 1e-9;
        let x = |psi: f64| (alpha + rho * psi.clamp(-edge, edge).tan()) / w_len;
        let (x0, x1) = (x(lo).max(-1.0), x(hi).min(1.0));
        (x0 <= x1).then_some((x0, x1))
    };
    let x = range(face.row(0).truncate())?;
    let y = range(face.row(1).truncate())?;
    Some([x.0, x.1, y.0, y.1])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nodes::shadow_map::tests::uniform;
    use crate::nodes::ShadowMapNode;
    use crate::scene::Light;
    use crate::{PointLight, SpotLight};
    use glam::{DVec3, DVec4, Vec3};

    /// The blocks' margin is the shaders' (a wider cone in the shaders would estimate cells
    /// outside the blocks, which would stay lit).
    #[test]
    fn the_cone_margin_is_the_shaders() {
        let line = include_str!("../../../shaders/shared/pcss.wgsl")
            .lines()
            .find(|l| l.starts_with("const PENUMBRA_CONE_MARGIN: f32 = "))
            .expect("pcss.wgsl declares the margin");
        let value: f64 = line
            .trim_start_matches("const PENUMBRA_CONE_MARGIN: f32 = ")
            .trim_end_matches(';')
            .parse()
            .unwrap();
        assert_eq!(value, PENUMBRA_CONE_MARGIN);
    }

    /// The layers of a point light (the node's cube faces) and of a spot (its one face) at a
    /// seeded place and scale.
    fn seeded_layers(next: &mut impl FnMut() -> f32, spot: bool) -> (Vec3, f32, Vec<glam::Mat4>) {
        let scale = 10f32.powf(2.0 + 3.5 * next());
        let light = Vec3::new(next(), next(), next()) * scale;
        let light_at = if spot {
            let aim = Vec3::new(next(), next(), next()).normalize_or(Vec3::Z);
            SpotLight::new(light, aim, 1.0 + 0.9 * next(), Vec3::ONE)
                .unwrap()
                .into()
        } else {
            Light::from(PointLight::new(light, Vec3::ONE).unwrap())
        };
        let faces = ShadowMapNode::face_matrices(&light_at, 1e-3 * scale, 0.1 * scale);
        (light, scale, faces)
    }

    /// A direction within `theta` of `axis`: at `along` (0 to 1) of the way out to its
    /// edge, at angle `around` about it.
    fn in_cap(axis: DVec3, theta: f64, along: f64, around: f64) -> DVec3 {
        let (e1, e2) = axis.any_orthonormal_pair();
        let t = theta * along;
        axis * t.cos() + (e1 * around.cos() + e2 * around.sin()) * t.sin()
    }

    /// `cap_ndc` holds every direction of the cap a layer projects (its NDC within the box),
    /// and no more than the cap needs: the box is the extremes of 720 points of its edge, to 1e-4.
    /// 400 seeded caps (half-angles 0.01 to 1.4 radians) over cube faces and spot layers,
    /// 720 directions of each cap's edge and 400 inside. A box from a cap 10% narrower misses
    /// directions, so it can tell.
    #[test]
    fn the_cap_s_box_holds_its_directions() {
        let mut next = uniform(0x9e37_79b9_7f4a_7c15);
        let (mut checked, mut tight) = (0, 0);
        for case in 0..400 {
            let (light, scale, faces) = seeded_layers(&mut next, case % 2 == 1);
            let axis = DVec3::new(next().into(), next().into(), next().into())
                .try_normalize()
                .unwrap_or(DVec3::Z);
            let theta = 0.01 + 1.39 * f64::from(next().abs());
            for face in &faces {
                let m = face.as_dmat4();
                let project = |d: DVec3| {
                    // At the scale's distance, as the grid's points (the f32 matrix projects
                    // the light itself only to within its rounding).
                    let c = m * (light.as_dvec3() + d * f64::from(scale)).extend(1.0);
                    (c.w > 0.0).then(|| (c.x / c.w, c.y / c.w))
                };
                let boxed = cap_ndc(&m, axis, theta);
                // The edge's extremes, each axis clamped to the layer as the box is.
                let mut seen = [
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                ];
                for k in 0..1120 {
                    let (along, around) = if k < 720 {
                        (1.0, f64::from(k) / 720.0 * std::f64::consts::TAU)
                    } else {
                        (
                            f64::from(next().abs()),
                            f64::from(next()) * std::f64::consts::PI,
                        )
                    };
                    let Some((x, y)) = project(in_cap(axis, theta, along, around)) else {
                        continue;
                    };
                    if k < 720 {
                        let (cx, cy) = (x.clamp(-1.0, 1.0), y.clamp(-1.0, 1.0));
                        seen = [
                            seen[0].min(cx),
                            seen[1].max(cx),
                            seen[2].min(cy),
                            seen[3].max(cy),
                        ];
                    }
                    if x.abs() > 1.0 || y.abs() > 1.0 {
                        continue;
                    }
                    let b = boxed
                        .unwrap_or_else(|| panic!("case {case}: ({x}, {y}) in the layer, no box"));
                    let slack = 1e-6; // the f32 matrix's rounding
                    assert!(
                        x >= b[0] - slack
                            && x <= b[1] + slack
                            && y >= b[2] - slack
                            && y <= b[3] + slack,
                        "case {case}: ({x}, {y}) outside {b:?}"
                    );
                    checked += 1;
                }
                if let Some(b) = boxed {
                    if seen[0] <= seen[1] && seen[2] <= seen[3] {
                        let gap = (0..4).map(|i| (b[i] - seen[i]).abs()).fold(0.0, f64::max);
                        assert!(
                            gap < 1e-4 || b == [-1.0, 1.0, -1.0, 1.0],
                            "case {case}: box {b:?}, edge {seen:?}"
                        );
                        tight += 1;
                    }
                }
            }
        }
        eprintln!("{checked} directions inside their boxes; {tight} boxes at the edge's extremes");
        assert!(checked > 100_000 && tight > 400, "{checked}, {tight}");
    }

    /// Every cell a penumbra cone reaches, as the shaders' `may_be_hidden` draws the cone, and
    /// its neighbours two cells each way lie in `penumbra_blocks`' blocks. 300 seeded lights
    /// (point and spot, scales 1e-2 to 1e5) with one to three spheres.
    #[test]
    fn the_blocks_hold_every_cell_of_the_cones() {
        let mut next = uniform(0x2545_f491_4f6c_dd1d);
        let n = 64u32;
        let mut reached = 0;
        for case in 0..300 {
            let (light, scale, faces) = seeded_layers(&mut next, case % 2 == 1);
            let radius = scale * (0.01 + 0.2 * next().abs());
            let count = 1 + case % 3;
            let mut spheres = [[0.0; 4]; MAX_SOFT_SPHERES];
            for sphere in spheres.iter_mut().take(count) {
                let at = light + Vec3::new(next(), next(), next()) * 3.0 * scale;
                *sphere = at.extend(scale * (0.05 + 0.5 * next().abs())).to_array();
            }
            let blocks = penumbra_blocks(
                &faces,
                light,
                radius,
                SoftLight {
                    spheres: count as u32,
                    ..SoftLight::default()
                },
                &spheres,
                n,
            );
            for sphere in &spheres[..count] {
                let to_c = DVec3::new(sphere[0].into(), sphere[1].into(), sphere[2].into())
                    - light.as_dvec3();
                let sin_t = PENUMBRA_CONE_MARGIN * (f64::from(radius) + f64::from(sphere[3]))
                    / to_c.length();
                if sin_t >= 0.99 {
                    continue; // every block (checked by the first case that has one)
                }
                for _ in 0..400 {
                    let along = f64::from(next().abs()).sqrt();
                    let d = in_cap(
                        to_c.normalize(),
                        sin_t.asin(),
                        along,
                        f64::from(next()) * 4.0,
                    );
                    for (layer, face) in faces.iter().enumerate() {
                        // At the sphere's distance, as the grid's points.
                        let c =
                            face.as_dmat4() * (light.as_dvec3() + d * to_c.length()).extend(1.0);
                        let ndc = DVec4::new(c.x / c.w, c.y / c.w, 0.0, 0.0);
                        if !(c.w > 0.0 && ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0) {
                            continue;
                        }
                        let cell = |t: f64| {
                            ((t * f64::from(n) - 0.5).round() as i64).clamp(0, i64::from(n) - 1)
                        };
                        let (cx, cy) = (cell((ndc.x + 1.0) / 2.0), cell((1.0 - ndc.y) / 2.0));
                        let b = blocks[layer];
                        for (x, y) in [(cx - 2, cy - 2), (cx + 2, cy + 2)] {
                            let (x, y) = (
                                x.clamp(0, i64::from(n) - 1) / 2,
                                y.clamp(0, i64::from(n) - 1) / 2,
                            );
                            assert!(
                                x >= i64::from(b[0]) && x < i64::from(b[2]) && y >= i64::from(b[1]) && y < i64::from(b[3]),
                                "case {case}: cell ({cx}, {cy}) of layer {layer} outside blocks {b:?}"
                            );
                        }
                        reached += 1;
                    }
                }
            }
        }
        eprintln!("{reached} directions of the cones in their blocks");
        assert!(reached > 50_000, "{reached}");
    }
}
