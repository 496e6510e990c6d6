//! How the shaders evaluate WGSL's transcendental built-ins: `shaders/precision.wgsl` (one
//! wrapper per built-in, and the polynomials used where WGSL's guarantees are too weak) and the
//! [`ShaderPrecision`] it is compiled at. `docs/METHOD.md` ("Precision on GPUs") says what each
//! kernel assumes and why it holds.

/// `shaders/precision.wgsl` as written (its wrappers at [`ShaderPrecision::Native`]).
pub(crate) const WGSL: &str = include_str!("../../shaders/precision.wgsl");
/// The line of `precision.wgsl` that selects what its wrappers compute (see [`ShaderPrecision`]).
const PRECISION_LINE: &str = "const VOLSHADOW_PRECISION: u32 = 0u;";

/// How the shaders evaluate WGSL's transcendental built-ins (`sin`, `exp`, `atan2`, …), each of
/// which they call through one wrapper.
///
/// A renderer uses [`ShaderPrecision::Native`], the default. WGSL promises far less of these
/// functions than most drivers give (`sin` and `cos`: an absolute error of 2^-11; `atan2`: 4096
/// ULP; `exp`: 3 + 2·|x| ULP; subnormals may flush to zero), and a CPU driver such as lavapipe
/// is nearly exact, so an image that is right there may still be wrong on a GPU.
/// [`ShaderPrecision::WorstCase`] makes every wrapper return the built-in's result moved by the
/// largest error WGSL allows and flush subnormal results to zero: the crate's accuracy tests run
/// in it on lavapipe, with their usual bounds. It costs time and is never a renderer's setting.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum ShaderPrecision {
    /// The built-ins as the driver implements them.
    #[default]
    Native,
    /// Each built-in's result moved by the largest error WGSL allows for it, in the direction
    /// given, and subnormal results flushed to zero (a test mode).
    WorstCase(ErrorSign),
}

/// The direction of [`ShaderPrecision::WorstCase`]'s errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorSign {
    /// Every result moved up.
    Up,
    /// Every result moved down.
    Down,
    /// Up or down by a hash of the argument's bits, as a real GPU's error changes sign from
    /// one argument to the next.
    Mixed,
}

impl ShaderPrecision {
    /// Every precision, the native one first.
    pub const ALL: [ShaderPrecision; 4] = [
        ShaderPrecision::Native,
        ShaderPrecision::WorstCase(ErrorSign::Up),
        ShaderPrecision::WorstCase(ErrorSign::Down),
        ShaderPrecision::WorstCase(ErrorSign::Mixed),
    ];

    /// `VOLSHADOW_PRECISION` in `precision.wgsl`.
    pub(crate) fn mode(self) -> u32 {
        match self {
            ShaderPrecision::Native => 0,
            ShaderPrecision::WorstCase(ErrorSign::Up) => 1,
            ShaderPrecision::WorstCase(ErrorSign::Down) => 2,
            ShaderPrecision::WorstCase(ErrorSign::Mixed) => 3,
        }
    }
}

/// `precision.wgsl` with its wrappers set to `precision`.
pub(crate) fn wgsl(precision: ShaderPrecision) -> String {
    debug_assert!(WGSL.contains(PRECISION_LINE));
    WGSL.replacen(
        PRECISION_LINE,
        &format!("const VOLSHADOW_PRECISION: u32 = {}u;", precision.mode()),
        1,
    )
}

#[cfg(test)]
mod tests {
    use super::{wgsl, ErrorSign, ShaderPrecision, PRECISION_LINE};
    use crate::HeadlessGpu;

    #[test]
    fn each_precision_sets_its_mode_line() {
        assert!(wgsl(ShaderPrecision::Native).contains(PRECISION_LINE));
        for (i, p) in ShaderPrecision::ALL.into_iter().enumerate() {
            let line = format!("const VOLSHADOW_PRECISION: u32 = {i}u;");
            assert_eq!(wgsl(p).matches(&line).count(), 1, "{p:?}");
            assert_eq!(wgsl(p).matches("const VOLSHADOW_PRECISION").count(), 1);
        }
    }

    /// Per argument pair (x, y): sin_poly(x), cos_poly(x), atan2_poly(y, x), vs_sin(x), then
    /// vs_exp(y), vs_atan2(y, x), acos_poly(c), asin_poly(c) with c = clamp(y, −1, 1).
    const KERNEL: &str = r#"
@group(0) @binding(0) var<storage, read> args: array<vec2<f32>>;
@group(0) @binding(1) var<storage, read_write> out: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= arrayLength(&args)) {
        return;
    }
    let a = args[i];
    let c = clamp(a.y, -1.0, 1.0);
    out[2u * i] = vec4<f32>(vs_sin_poly(a.x), vs_cos_poly(a.x), vs_atan2_poly(a.y, a.x), vs_sin(a.x));
    out[2u * i + 1u] = vec4<f32>(vs_exp(a.y), vs_atan2(a.y, a.x), vs_acos_poly(c), vs_asin_poly(c));
}
"#;

    fn run(gpu: &HeadlessGpu, precision: ShaderPrecision, args: &[[f32; 2]]) -> Vec<[f32; 4]> {
        use wgpu::util::DeviceExt;
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("precision test"),
            source: wgpu::ShaderSource::Wgsl(format!("{}\n{KERNEL}", wgsl(precision)).into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: None,
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: None,
            contents: bytemuck::cast_slice(args),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let output = device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: (args.len() * 32) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: input.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: output.as_entire_binding(),
                },
            ],
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = crate::gpu::passes::begin_compute(&mut encoder, &Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((args.len() as u32).div_ceil(64), 1, 1);
        }
        gpu.submit_and_wait(encoder).unwrap();
        bytemuck::pod_collect_to_vec(&gpu.read_buffer_bytes(&output).unwrap())
    }

    fn rel(got: f32, want: f64) -> f64 {
        (f64::from(got) - want).abs() / want.abs().max(f64::MIN_POSITIVE)
    }

    /// The polynomials the shaders use where WGSL's built-ins are too weak, against f64, at
    /// every precision (they call no built-in, so the worst case must not move them): sin to
    /// 5 ULP relative on [−π/2 − 0.1, π/2 + 0.1], down to 1e-30; cos to 2e-7 absolute; atan2
    /// to 1e-6 relative for ratios from 1e-7 to 1e7 in all four quadrants (an angle near π
    /// and its small supplement both); acos and asin to 1e-6 relative. In the worst case
    /// WGSL's own `sin` and `atan2` miss those bounds by far on the same arguments (what the
    /// polynomials are for), and `exp` of −93 (4e-41, subnormal) is flushed to zero.
    #[test]
    fn the_polynomials_hold_their_bounds_and_the_worst_case_is_live() {
        let gpu = match HeadlessGpu::new() {
            Ok(gpu) => gpu,
            Err(e) => panic!("GPU tests need a wgpu adapter (lavapipe works): {e}"),
        };
        let mut rng = fastrand::Rng::with_seed(31);
        let half_pi = std::f64::consts::FRAC_PI_2;
        let mut args: Vec<[f32; 2]> = (0..8192)
            .map(|i| {
                let x = if i % 2 == 0 {
                    (rng.f64() * 2.0 - 1.0) * (half_pi + 0.1)
                } else {
                    10f64.powf(-30.0 + 30.0 * rng.f64()) * if rng.bool() { 1.0 } else { -1.0 }
                };
                let ratio = 10f64.powf(-7.0 + 14.0 * rng.f64());
                let sx = if rng.bool() { 1.0 } else { -1.0 };
                let sy = if rng.bool() { 1.0 } else { -1.0 };
                let scale = 10f64.powf(-3.0 + 6.0 * rng.f64());
                if i % 3 == 0 {
                    // x as the atan2 abscissa: keep it the sine's argument too.
                    [x as f32, (x.abs() * ratio * sy) as f32]
                } else {
                    [(scale * sx) as f32, (scale * ratio * sy) as f32]
                }
            })
            .collect();
        // exp's argument and the flush: e^-93 is subnormal in f32.
        args.push([0.5, -93.0]);
        let flush = args.len() - 1;
        for precision in ShaderPrecision::ALL {
            let out = run(&gpu, precision, &args);
            let (mut sin_err, mut cos_err, mut atan_err, mut inv_err) =
                (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            let (mut builtin_sin, mut builtin_atan) = (0.0f64, 0.0f64);
            for (a, o) in args.iter().zip(out.chunks(2)) {
                let (x, y) = (f64::from(a[0]), f64::from(a[1]));
                if x.abs() <= half_pi + 0.1 {
                    sin_err = sin_err.max(rel(o[0][0], x.sin()) / f64::from(f32::EPSILON));
                    cos_err = cos_err.max((f64::from(o[0][1]) - x.cos()).abs());
                    builtin_sin = builtin_sin.max(rel(o[0][3], x.sin()));
                }
                if y != 0.0 || x != 0.0 {
                    atan_err = atan_err.max(rel(o[0][2], y.atan2(x)));
                    builtin_atan = builtin_atan.max(rel(o[1][1], y.atan2(x)));
                }
                let c = y.clamp(-1.0, 1.0);
                inv_err = inv_err.max(rel(o[1][2], c.acos()));
                if c != 0.0 {
                    inv_err = inv_err.max(rel(o[1][3], c.asin()));
                }
            }
            println!(
                "{precision:?}: sin_poly {sin_err:.2} ULP, cos_poly {cos_err:.2e} absolute, \
                 atan2_poly {atan_err:.2e}, acos/asin_poly {inv_err:.2e} relative; the built-ins: \
                 sin {builtin_sin:.2e}, atan2 {builtin_atan:.2e} relative; exp(-93) = {:e}",
                out[2 * flush + 1][0]
            );
            assert!(sin_err <= 5.0, "{precision:?}: sin_poly {sin_err} ULP");
            assert!(cos_err <= 2e-7, "{precision:?}: cos_poly {cos_err}");
            assert!(atan_err <= 1e-6, "{precision:?}: atan2_poly {atan_err}");
            assert!(inv_err <= 1e-6, "{precision:?}: acos/asin_poly {inv_err}");
            if let ShaderPrecision::WorstCase(sign) = precision {
                // Live: the built-ins miss the polynomials' bounds by orders of magnitude.
                assert!(
                    builtin_sin > 1e3 * 5.0 * f64::from(f32::EPSILON),
                    "{sign:?}: sin {builtin_sin}"
                );
                assert!(builtin_atan > 1e-4, "{sign:?}: atan2 {builtin_atan}");
                assert_eq!(out[2 * flush + 1][0], 0.0, "{sign:?}: exp(-93) not flushed");
                if sign == ErrorSign::Up {
                    // sin(0.5) moved up by exactly WGSL's 2^-11.
                    let moved = f64::from(out[2 * flush][3]) - 0.5f64.sin();
                    assert!(
                        (moved - 2f64.powi(-11)).abs() < 1e-6,
                        "sin moved by {moved}"
                    );
                }
            }
        }
    }
}
