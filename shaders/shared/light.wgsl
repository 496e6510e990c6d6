// What the passes ask of a light, each question one choice on the `LIGHT` pipeline constant
// (prelude.wgsl) among the kinds' own answers, one file per kind in `light/`: the airlight
// ray, T along it, the normalised scattering angle s of a distance and back, the lit support
// in s and in distance, and the unshadowed T over it. A pass that asks imports this file.
// (The shadow map's layer of a point, the other question, is pcss.wgsl's.)
#import light/point.wgsl
#import light/spot.wgsl
#import light/directional.wgsl

fn air_ray(a: Airlight, ray: PixelRay) -> AirRay {
    if (LIGHT == LIGHT_DIRECTIONAL) {
        return directional_air_ray(a, ray);
    }
    return point_air_ray(a, ray);
}

// T at s both ways: from the eye (head) and to the end (tail).
fn table_tt(table: texture_2d<f32>, a: Airlight, r: AirRay, s: f32) -> TT {
    if (LIGHT == LIGHT_DIRECTIONAL) {
        return directional_tt(a, s);
    }
    return point_tt(table, a, r, s);
}

fn s_of_x(a: Airlight, r: AirRay, x: f32) -> f32 {
    if (LIGHT == LIGHT_DIRECTIONAL) {
        return directional_s(a, x);
    }
    return point_s_of_x(a, r, x);
}

fn light_x_of_s(a: Airlight, r: AirRay, s: f32) -> f32 {
    if (LIGHT == LIGHT_DIRECTIONAL) {
        return directional_x(a, s);
    }
    return point_x_of_s(a, r, s);
}

// The lit support of a ray in s (`light` read for a spot's cone).
fn support_s(a: Airlight, r: AirRay, light: Light, dir: vec3<f32>, x_end: f32) -> SupportS {
    if (LIGHT == LIGHT_SPOT) {
        return spot_support_s(a, r, light, dir, x_end);
    }
    if (LIGHT == LIGHT_DIRECTIONAL) {
        return directional_support_s(a, x_end);
    }
    return point_support_s(a, r, x_end);
}

// The lit support of a ray in distance, within [0, x_end].
fn support_x(a: Airlight, light: Light, dir: vec3<f32>, x_end: f32) -> Support {
    if (LIGHT == LIGHT_SPOT) {
        return cone_support(a, light, dir, x_end);
    }
    var sup: Support;
    sup.count = 1u;
    sup.x[0] = vec2<f32>(0.0, x_end);
    return sup;
}

// Unshadowed T over the lit support.
fn unshadowed_t(table: texture_2d<f32>, a: Airlight, r: AirRay, sup: SupportS) -> vec3<f32> {
    if (LIGHT == LIGHT_SPOT) {
        return spot_unshadowed_t(table, a, r, sup);
    }
    if (LIGHT == LIGHT_DIRECTIONAL) {
        return directional_unshadowed_t(a, sup);
    }
    return point_unshadowed_t(table, a, r, sup);
}
