// A spot light's answers (`light.wgsl` chooses them by `LIGHT`): a point light
// (`light/point.wgsl`) whose rays are limited to its cone, so its lit support along a ray is
// the ray's pieces inside the cone, up to two.
#import light/point.wgsl

// Whether `p` is inside `light`'s cone (apex at the airlight's light position).
fn inside_cone(a: Airlight, light: Light, p: vec3<f32>) -> bool {
    let rel = p - a.light_pos;
    return dot(light.axis, rel) >= light.cos_half * length(rel);
}

// The ray eye + x·dir, x in [0, x_end], cut where it crosses the double cone with apex `apex`,
// unit axis `axis` and squared cosine of the half-angle `c2`: pieces i = [x[i], x[i + 1]] for
// i < count, each inside or outside the cone throughout. The quadratic's roots are taken
// without cancellation.
struct ConeCuts {
    x: array<f32, 4>,
    count: u32,
}

fn cone_cuts(apex: vec3<f32>, axis: vec3<f32>, c2: f32, eye: vec3<f32>, dir: vec3<f32>, x_end: f32) -> ConeCuts {
    let w0 = eye - apex;
    let av = dot(axis, dir);
    let aw = dot(axis, w0);
    let qa = av * av - c2;
    let qb = 2.0 * (av * aw - c2 * dot(dir, w0));
    let qc = aw * aw - c2 * dot(w0, w0);
    var roots = array<f32, 2>(-1.0, -1.0);
    // qa is dimensionless (qb a length, qc an area): whether it is zero is decided against its
    // own terms' rounding, not against qb or qc, which grow with the scene's scale (at a unit of
    // 8e4 a threshold of 1e-12 · |qc| took rays nearly parallel to the cone's surface for
    // linear and cut them wrong, by up to 8%). Below it qa is rounding noise, and the linear
    // root is the one kept.
    if (abs(qa) > 1.0e-6 * max(av * av, c2)) {
        // The discriminant qb² − 4·qa·qc in the closed form 4·c2·(|axis × n|² − c2·|n|²),
        // n = dir × w0 (|n| is the ray's distance from the apex): a ray passing near the apex
        // has two nearly equal roots, one on each nappe, and qb² − 4·qa·qc cancels to rounding
        // noise there (relative 1e-7 of qb²), often negative. For a cone of nearly 180° the
        // two nappes nearly coincide with the plane through the apex, so every ray that
        // crosses that plane near the light was such a ray: its whole lit piece was lost
        // (black pixels at 179.95°, the whole light's row at 179.999°).
        let n = cross(dir, w0);
        let an = cross(axis, n);
        let disc = 4.0 * c2 * (dot(an, an) - c2 * dot(n, n));
        if (disc >= 0.0) {
            let q = -0.5 * (qb + select(-1.0, 1.0, qb >= 0.0) * vs_sqrt(disc));
            let r0 = q / qa;
            let r1 = select(r0, qc / q, q != 0.0);
            roots = array<f32, 2>(min(r0, r1), max(r0, r1));
        }
    } else if (qb != 0.0) {
        roots[0] = -qc / qb;
    }
    var cuts: ConeCuts;
    // The roots inside (0, x_end), in order, written at fixed indices: a private array
    // written or read at a variable index lives in memory on llvmpipe, for every lane.
    let in0 = roots[0] > 0.0 && roots[0] < x_end;
    let in1 = roots[1] > 0.0 && roots[1] < x_end;
    let first = select(select(x_end, roots[1], in1), roots[0], in0);
    let second = select(x_end, roots[1], in0 && in1);
    cuts.x = array<f32, 4>(0.0, first, second, x_end);
    cuts.count = 1u + select(0u, 1u, in0) + select(0u, 1u, in1);
    return cuts;
}

// Piece i (< count) of `c`: [x[i], x[i + 1]], read at fixed indices (see `cone_cuts`).
fn cut_piece(c: ConeCuts, i: u32) -> vec2<f32> {
    let x = c.x;
    return select(select(vec2<f32>(x[2], x[3]), vec2<f32>(x[1], x[2]), i == 1u), vec2<f32>(x[0], x[1]), i == 0u);
}

// The ray's pieces inside the cone, up to two (`Support`): roots of (a·(X − P))² = cos²α |X − P|²
// on the light's nappe a·(X − P) ≥ 0. The cone's apex is the airlight's light position
// (`air.light_pos`, where the eye–light distance is kept above zero).
fn cone_support(air: Airlight, light: Light, dir: vec3<f32>, x_end: f32) -> Support {
    var sup: Support;
    sup.count = 0u;
    // Split [0, x_end] at the cone's crossings and keep the pieces whose midpoint is inside it.
    var cuts = cone_cuts(air.light_pos, light.axis, light.cos_half * light.cos_half, air.eye, dir, x_end);
    let k = cuts.count;
    for (var i = 0u; i < k; i++) {
        let piece = cut_piece(cuts, i);
        let a = piece.x;
        let b = piece.y;
        var mid = 0.5 * (a + b);
        if (b >= FAR) {
            mid = a + 1.0 + 2.0 * abs(a) + 1.0e3 * air.distance; // far along an unbounded piece
        }
        if (b > a && inside_cone(air, light, air.eye + mid * dir)) {
            if (sup.count > 0u && sup.x[sup.count - 1u].y == a) {
                sup.x[sup.count - 1u].y = b;
            } else if (sup.count < 2u) {
                sup.x[sup.count] = vec2<f32>(a, b);
                sup.count++;
            }
        }
    }
    return sup;
}

// The lit support in s: the ray's pieces inside `light`'s cone.
fn spot_support_s(a: Airlight, r: AirRay, light: Light, dir: vec3<f32>, x_end: f32) -> SupportS {
    var out: SupportS;
    let cone = cone_support(a, light, dir, x_end);
    out.count = cone.count;
    for (var i = 0u; i < cone.count; i++) {
        out.s[i] = vec2<f32>(point_s_of_x(a, r, cone.x[i].x), point_s_of_x(a, r, cone.x[i].y));
    }
    return out;
}

// Unshadowed T over the lit support: each piece from T at its two ends.
fn spot_unshadowed_t(table: texture_2d<f32>, a: Airlight, r: AirRay, sup: SupportS) -> vec3<f32> {
    var t = vec3<f32>(0.0);
    for (var i = 0u; i < sup.count; i++) {
        t += t_between(point_tt(table, a, r, sup.s[i].x), point_tt(table, a, r, sup.s[i].y));
    }
    return t;
}
