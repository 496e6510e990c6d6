// volshadow precision: every transcendental built-in the shaders call goes through one wrapper
// here (`vs_sin`, `vs_exp3`, …), and the maths that WGSL's guarantees are too weak for has its
// own polynomial (`vs_sin_poly`, `vs_atan2_poly`, …) built from +, −, × and one division, which WGSL
// rounds correctly (division within 2.5 ULP).
//
// WGSL guarantees (f32), and what the wrappers assume of the built-ins:
//   sin, cos     absolute error ≤ 2^-11 on [−π, π], nothing outside: never used where the result
//                may be small relative to that (use `vs_sin_poly` / `vs_cos_poly`), nor outside [−π, π]
//   tan          as sin / cos
//   exp, exp2    3 + 2·|x| ULP; the result may be subnormal, and a GPU may flush it to 0
//   log, log2    absolute 2^-21 on [0.5, 2], 3 ULP elsewhere
//   pow          as exp2(y · log2(x))
//   atan, atan2  4096 ULP (5e-4 relative): never used where an angle near π (or its
//                complement) matters (use `vs_atan2_poly`)
//   asin, acos   as atan2(x, sqrt(1 − x²)) and atan2(sqrt(1 − x²), x)
//   asinh        as log(x + sqrt(x² + 1))
//   sqrt         as 1 / inverseSqrt (2 ULP); the polynomials below call it directly (a few
//                ULP is all they need of it)
//
// `VOLSHADOW_PRECISION` selects what the wrappers compute. 0 (the default, and the only value a
// renderer uses): the built-in itself. 1, 2, 3 (a test build, `volshadow::ShaderPrecision::
// WorstCase`): the built-in plus the largest error WGSL allows for it, upwards (1), downwards
// (2), or with a sign taken from a hash of the argument's bits (3), and every result below f32's
// normal range flushed to zero, as NVIDIA's GPUs flush subnormals. On a driver whose maths is
// nearly exact (lavapipe), the worst-case build shows what the least precise conforming GPU
// may do to an image.
const VOLSHADOW_PRECISION: u32 = 0u;

const VS_F32_MIN_NORMAL: f32 = 1.17549435e-38;

// The sign of a worst-case error: +1, −1, or from a hash of the argument's bits (a real GPU's
// error changes sign from one argument to the next).
fn vs_error_sign(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 1u) {
        return 1.0;
    }
    if (VOLSHADOW_PRECISION == 2u) {
        return -1.0;
    }
    var h = bitcast<u32>(x) * 0x9E3779B1u;
    h ^= h >> 15u;
    h *= 0x85EBCA77u;
    h ^= h >> 13u;
    return select(-1.0, 1.0, (h & 1u) == 0u);
}

// Flushes a subnormal to zero (keeps its sign), as a GPU that flushes subnormals does.
fn vs_ftz(x: f32) -> f32 {
    return select(x, 0.0 * x, abs(x) < VS_F32_MIN_NORMAL);
}

fn vs_ftz3(v: vec3<f32>) -> vec3<f32> {
    return select(v, 0.0 * v, abs(v) < vec3<f32>(VS_F32_MIN_NORMAL));
}

// One unit in the last place of a normal y (0 for 0, ∞ for ∞ and NaN).
fn vs_ulp(y: f32) -> f32 {
    let e = bitcast<u32>(y) & 0x7f800000u;
    if (e == 0x7f800000u) {
        return 0.0;
    }
    // 2^(exponent − 23): the exponent field less 23, or the smallest subnormal step below.
    let shifted = i32(e >> 23u) - 23;
    if (shifted <= 0) {
        return 0.0;
    }
    return bitcast<f32>(u32(shifted) << 23u);
}

// y moved by `ulps` units in its last place, in the worst case's direction for argument x.
fn vs_ulps(y: f32, ulps: f32, x: f32) -> f32 {
    return vs_ftz(y + vs_error_sign(x) * ulps * vs_ulp(y));
}

fn vs_sin(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return sin(x);
    }
    // Outside [−π, π] WGSL bounds nothing: an error of 1 shows any use that relies on it.
    let bound = select(1.0, 0.00048828125, abs(x) <= VS_PI);
    return vs_ftz(sin(x) + vs_error_sign(x) * bound);
}

fn vs_cos(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return cos(x);
    }
    let bound = select(1.0, 0.00048828125, abs(x) <= VS_PI);
    return vs_ftz(cos(x) + vs_error_sign(x) * bound);
}

fn vs_tan(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return tan(x);
    }
    return vs_sin(x) / vs_cos(x);
}

fn vs_exp(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return exp(x);
    }
    return vs_ulps(exp(x), 3.0 + 2.0 * abs(x), x);
}

fn vs_exp2(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return exp2(x);
    }
    return vs_ulps(exp2(x), 3.0 + 2.0 * abs(x), x);
}

fn vs_log(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return log(x);
    }
    let y = log(vs_ftz(x));
    if (x >= 0.5 && x <= 2.0) {
        return vs_ftz(y + vs_error_sign(x) * 4.76837158e-7); // 2^-21
    }
    return vs_ulps(y, 3.0, x);
}

fn vs_log2(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return log2(x);
    }
    let y = log2(vs_ftz(x));
    if (x >= 0.5 && x <= 2.0) {
        return vs_ftz(y + vs_error_sign(x) * 4.76837158e-7);
    }
    return vs_ulps(y, 3.0, x);
}

fn vs_pow(x: f32, y: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return pow(x, y);
    }
    return vs_exp2(y * vs_log2(x));
}

fn vs_inverse_sqrt(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return inverseSqrt(x);
    }
    return vs_ulps(inverseSqrt(vs_ftz(x)), 2.0, x);
}

fn vs_sqrt(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return sqrt(x);
    }
    return vs_ftz(1.0 / vs_inverse_sqrt(x));
}

fn vs_atan(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return atan(x);
    }
    return vs_ulps(atan(x), 4096.0, x);
}

fn vs_atan2(y: f32, x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return atan2(y, x);
    }
    return vs_ulps(atan2(y, x), 4096.0, y + x);
}

fn vs_asin(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return asin(x);
    }
    return vs_atan2(x, vs_sqrt((1.0 - x) * (1.0 + x)));
}

fn vs_acos(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return acos(x);
    }
    return vs_atan2(vs_sqrt((1.0 - x) * (1.0 + x)), x);
}

fn vs_asinh(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return asinh(x);
    }
    return select(1.0, -1.0, x < 0.0) * vs_log(abs(x) + vs_sqrt(x * x + 1.0));
}

fn vs_exp3(v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(vs_exp(v.x), vs_exp(v.y), vs_exp(v.z));
}

fn vs_log3(v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(vs_log(v.x), vs_log(v.y), vs_log(v.z));
}

fn vs_pow3(x: vec3<f32>, y: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(vs_pow(x.x, y.x), vs_pow(x.y, y.y), vs_pow(x.z, y.z));
}

const VS_PI: f32 = 3.14159265358979;

// sin x for |x| ≤ π/2 + 0.1 to a relative error of a few f32 ULP (its Taylor series to x¹⁵:
// the first term left out is below 2e-9 of the result there), from +, × alone: the relative
// precision of small angles that `sin`'s absolute 2^-11 loses.
fn vs_sin_poly(x: f32) -> f32 {
    let x2 = x * x;
    var p = -7.6471637318198164e-13;                       // −1/15!
    p = p * x2 + 1.6059043836821613e-10;                   // 1/13!
    p = p * x2 - 2.5052108385441720e-8;                    // −1/11!
    p = p * x2 + 2.7557319223985893e-6;                    // 1/9!
    p = p * x2 - 1.9841269841269841e-4;                    // −1/7!
    p = p * x2 + 8.3333333333333333e-3;                    // 1/5!
    p = p * x2 - 1.6666666666666667e-1;                    // −1/3!
    return x + x * x2 * p;
}

// cos x for |x| ≤ π/2 + 0.1 to an absolute error of a few 1e-8 (its Taylor series to x¹⁶).
// Where cos x is small relative to that, use vs_sin_poly of the complement computed exactly.
fn vs_cos_poly(x: f32) -> f32 {
    let x2 = x * x;
    var p = 4.7794773323873853e-14;                        // 1/16!
    p = p * x2 - 1.1470745597729725e-11;                   // −1/14!
    p = p * x2 + 2.0876756987868099e-9;                    // 1/12!
    p = p * x2 - 2.7557319223985891e-7;                    // −1/10!
    p = p * x2 + 2.4801587301587302e-5;                    // 1/8!
    p = p * x2 - 1.3888888888888889e-3;                    // −1/6!
    p = p * x2 + 4.1666666666666667e-2;                    // 1/4!
    p = p * x2 - 0.5;
    return 1.0 + x2 * p;
}

// atan t for |t| ≤ tan(π/8) to a relative error of a few f32 ULP (its series to t¹⁹: the first
// term left out is below 2e-9 of the result).
fn vs_atan_poly_small(t: f32) -> f32 {
    let t2 = t * t;
    var p = -1.0 / 21.0;
    p = p * t2 + 1.0 / 19.0;
    p = p * t2 - 1.0 / 17.0;
    p = p * t2 + 1.0 / 15.0;
    p = p * t2 - 1.0 / 13.0;
    p = p * t2 + 1.0 / 11.0;
    p = p * t2 - 1.0 / 9.0;
    p = p * t2 + 1.0 / 7.0;
    p = p * t2 - 1.0 / 5.0;
    p = p * t2 + 1.0 / 3.0;
    return t - t * t2 * p;
}

// atan2(y, x) to a relative error of about 1e-6 of its result for every (y, x), from +, −, ×
// and two divisions: a tiny angle keeps its relative precision (WGSL's atan2 promises only
// 4096 ULP), and so does π minus a tiny angle when asked as atan2(y, −x).
fn vs_atan2_poly(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    let hi = max(ax, ay);
    let lo = min(ax, ay);
    var a = 0.0;
    if (hi > 0.0) {
        let t = lo / hi; // [0, 1]
        if (t > 0.41421356237) {
            // π/4 + atan((t − 1)/(t + 1)): the series' argument stays below tan(π/8), and the
            // sum lies in [π/8, π/4], so nothing cancels.
            a = 0.78539816339744831 + vs_atan_poly_small((t - 1.0) / (t + 1.0));
        } else {
            a = vs_atan_poly_small(t);
        }
    }
    if (ay > ax) {
        a = 1.5707963267948966 - a;
    }
    if (x < 0.0) {
        a = VS_PI - a;
    }
    return select(a, -a, y < 0.0);
}

fn vs_sinh(x: f32) -> f32 {
    if (VOLSHADOW_PRECISION == 0u) {
        return sinh(x);
    }
    return (vs_exp(x) - vs_exp(-x)) * 0.5;
}

// tan x for x ∈ [0, π/2) to a few ULP relative (the cosine near π/2 as the sine of its
// complement).
fn vs_tan_poly(x: f32) -> f32 {
    if (x > 0.78539816339744831) {
        return vs_sin_poly(x) / vs_sin_poly(1.5707963267948966 - x);
    }
    return vs_sin_poly(x) / vs_cos_poly(x);
}

// (cos θ, sin θ) for θ ∈ [0, π], the sine to a few ULP relative near 0 and π, the cosine to
// about 1e-7 absolute.
fn vs_cos_sin_pi(theta: f32) -> vec2<f32> {
    if (theta > 1.5707963267948966) {
        let r = VS_PI - theta;
        return vec2<f32>(-vs_cos_poly(r), vs_sin_poly(r));
    }
    return vec2<f32>(vs_cos_poly(theta), vs_sin_poly(theta));
}

// acos and asin of x ∈ [−1, 1] through `vs_atan2_poly` (about 1e-6 relative), where WGSL's
// inherit atan2's 4096 ULP.
fn vs_acos_poly(x: f32) -> f32 {
    return vs_atan2_poly(sqrt(max((1.0 - x) * (1.0 + x), 0.0)), x);
}

fn vs_asin_poly(x: f32) -> f32 {
    return vs_atan2_poly(x, sqrt(max((1.0 - x) * (1.0 + x), 0.0)));
}
