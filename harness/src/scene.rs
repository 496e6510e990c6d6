//! Scenes of triangle meshes measured against the f64 reference: the caller's depth buffer is
//! ray-cast here (every visible mesh and an optional ground plane), the reference sees the same
//! meshes as occluders, and the error is reported as the issue tracker and the README state it.

use glam::{DMat4, DVec3, Mat4};
use volshadow::gpu::{Occluder, OccluderMesh};
use volshadow::nodes::{MarchSettings, UpsampleFilter};
use volshadow::reference::{self, LightSource, TriangleMesh};
use volshadow::scene::Mesh;
use volshadow::{Cache, Camera, HeadlessGpu, Light, Medium};

/// Occluder meshes (each also seen by the camera unless `visible` is false) over an optional
/// ground plane `y = ground` that the camera sees but that casts no shadow.
#[derive(Clone, Default)]
pub struct MeshScene {
    pub ground: Option<f64>,
    pub occluders: Vec<SceneMesh>,
}

#[derive(Clone)]
pub struct SceneMesh {
    pub mesh: Mesh,
    pub transform: Mat4,
    pub visible: bool,
}

impl MeshScene {
    pub fn add(&mut self, mesh: Mesh) -> &mut Self {
        self.occluders.push(SceneMesh {
            mesh,
            transform: Mat4::IDENTITY,
            visible: true,
        });
        self
    }

    /// World-space triangles of the visible meshes.
    fn visible_triangles(&self) -> Vec<[DVec3; 3]> {
        let mut out = Vec::new();
        for o in self.occluders.iter().filter(|o| o.visible) {
            let t: DMat4 = o.transform.as_dmat4();
            let p: Vec<DVec3> = o
                .mesh
                .positions()
                .iter()
                .map(|v| t.transform_point3(v.as_dvec3()))
                .collect();
            for tri in o.mesh.indices().chunks_exact(3) {
                out.push([p[tri[0] as usize], p[tri[1] as usize], p[tri[2] as usize]]);
            }
        }
        out
    }

    /// The caller's depth buffer for `camera` at `width` × `height`: the first visible mesh or
    /// the ground, ray-cast (the far depth where a ray meets neither).
    pub fn depths(&self, camera: &Camera, width: u32, height: u32) -> Vec<f32> {
        let tris = self.visible_triangles();
        (0..width * height)
            .map(|i| {
                let (o, d) = super::pixel_ray(camera, width, height, i % width, i / width);
                let ds = first_hit(&tris, self.ground, near_plane(camera), o, d);
                if ds.is_finite() {
                    super::ndc_depth(camera, o + ds * d)
                } else {
                    camera.far_depth()
                }
            })
            .collect()
    }

    pub fn reference_occluders(&self) -> Vec<reference::Occluder> {
        self.occluders
            .iter()
            .map(|o| {
                reference::Occluder::Mesh(TriangleMesh::from_indexed(
                    o.mesh.positions(),
                    o.mesh.indices(),
                    o.transform.as_dmat4(),
                ))
            })
            .collect()
    }
}

/// The camera's near plane as (view direction, view depth): what lies nearer is clipped, so
/// the caller's depth buffer holds what is behind it.
fn near_plane(camera: &Camera) -> (DVec3, f64) {
    let view = camera.view().as_dmat4();
    let inv_proj = camera.projection().as_dmat4().inverse();
    let near_ndc = if camera.far_depth() == 1.0 { 0.0 } else { 1.0 };
    let p = inv_proj * glam::DVec4::new(0.0, 0.0, near_ndc, 1.0);
    let forward = -view.inverse().z_axis.truncate().normalize();
    (forward, -p.z / p.w)
}

/// First hit of the ray `o + t d` (t > 0, beyond the camera's near plane `near`) with the
/// triangles or the ground (Möller–Trumbore).
fn first_hit(
    triangles: &[[DVec3; 3]],
    ground: Option<f64>,
    (forward, near): (DVec3, f64),
    o: DVec3,
    d: DVec3,
) -> f64 {
    let t_min = near / d.dot(forward).max(1e-12);
    let mut best = match ground {
        Some(y) if d.y < 0.0 && o.y > y && (y - o.y) / d.y > t_min => (y - o.y) / d.y,
        _ => f64::INFINITY,
    };
    for [a, b, c] in triangles {
        let e1 = *b - *a;
        let e2 = *c - *a;
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-300 {
            continue;
        }
        let inv = 1.0 / det;
        let s = o - *a;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            continue;
        }
        let q = s.cross(e1);
        let v = d.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            continue;
        }
        let t = e2.dot(q) * inv;
        if t > t_min && t < best {
            best = t;
        }
    }
    best
}

/// Errors of a GPU in-scatter image against the reference.
#[derive(Debug, Clone, Copy)]
pub struct Errors {
    /// 95th percentile of the per-pixel relative error max_c |gpu − ref| / max_c ref over
    /// pixels whose reference is above 1% of the frame's 99th-percentile brightness.
    pub p95: f64,
    /// Largest such error.
    pub max: f64,
    /// RMSE over all pixels and channels, relative to the mean in-scatter.
    pub rmse: f64,
    /// Pixels counted in the percentile.
    pub counted: usize,
    /// NaN, Inf or negative values in the GPU image.
    pub non_finite: usize,
    /// The pixel with the largest error (row-major index).
    pub worst: usize,
}

impl Errors {
    /// The p95 and RMSE alone, for a metric line.
    pub fn short(&self) -> String {
        format!(
            "p95 {:.3}%, RMSE {:.3}%",
            100.0 * self.p95,
            100.0 * self.rmse
        )
    }
}

impl std::fmt::Display for Errors {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "p95 {:.3}%, max {:.3}% (pixel {}), RMSE {:.3}% of the mean ({} pixels counted, {} non-finite)",
            100.0 * self.p95,
            100.0 * self.max,
            self.worst,
            100.0 * self.rmse,
            self.counted,
            self.non_finite
        )
    }
}

/// Compares `gpu` with `reference` (same layout), leaving out the light's own pixels
/// (`ImageError::keep_away_from_lights`), with the crate's metric (`volshadow::reference::ImageError`), as the
/// report does.
pub fn errors(
    gpu: &[[f32; 4]],
    reference: &[DVec3],
    camera: &Camera,
    light: &Light,
    (width, height): (u32, u32),
) -> Errors {
    let keep = reference::ImageError::keep_away_from_lights(camera, &[*light], width, height);
    let image: Vec<DVec3> = gpu
        .iter()
        .map(|t| DVec3::new(t[0].into(), t[1].into(), t[2].into()))
        .collect();
    let e = reference::ImageError::measure(&image, reference, &keep);
    Errors {
        p95: e.p95,
        max: e.max,
        worst: e.worst,
        rmse: e.rmse,
        counted: e.counted,
        non_finite: gpu
            .iter()
            .filter(|t| t[0..3].iter().any(|v| !v.is_finite() || *v < 0.0))
            .count(),
    }
}

/// A rendered and measured frame.
pub struct Measured {
    pub errors: Errors,
    pub frame: super::ShadowFrame,
    pub reference: Vec<DVec3>,
}

/// What to render: the scene, the view, the light and the method.
pub struct Shot<'a> {
    pub scene: &'a MeshScene,
    pub camera: &'a Camera,
    pub light: &'a Light,
    pub medium: &'a Medium,
    pub size: (u32, u32),
    pub shadow_resolution: u32,
    pub filter: UpsampleFilter,
    /// A spot light's texture: the GPU texture and the reference's light source.
    pub texture: Option<(&'a wgpu::Texture, &'a dyn LightSource)>,
}

impl<'a> Shot<'a> {
    pub fn new(
        scene: &'a MeshScene,
        camera: &'a Camera,
        light: &'a Light,
        medium: &'a Medium,
        size: u32,
    ) -> Self {
        Self {
            scene,
            camera,
            light,
            medium,
            size: (size, size),
            shadow_resolution: 1024,
            filter: UpsampleFilter::DepthAware3x3,
            texture: None,
        }
    }

    /// The reference image (compute once, compare with several methods).
    pub fn reference(&self) -> Vec<DVec3> {
        let tris = self.scene.visible_triangles();
        let ground = self.scene.ground;
        let occ = self.scene.reference_occluders();
        let (w, h) = self.size;
        let near = near_plane(self.camera);
        let distance = |o: DVec3, d: DVec3| first_hit(&tris, ground, near, o, d);
        match self.texture {
            Some((_, source)) => reference::inscatter_image(
                self.camera,
                w,
                h,
                distance,
                self.medium,
                &DynSource(source),
                &occ,
            ),
            None => reference::inscatter_image(
                self.camera,
                w,
                h,
                distance,
                self.medium,
                self.light,
                &occ,
            ),
        }
    }

    /// The reference image with `occluders` casting shadows in place of the scene's, and the
    /// scene's surfaces still seen (where the camera's rays end).
    pub fn reference_casting(&self, occluders: &[reference::Occluder]) -> Vec<DVec3> {
        let tris = self.scene.visible_triangles();
        let ground = self.scene.ground;
        let (w, h) = self.size;
        let near = near_plane(self.camera);
        let distance = |o: DVec3, d: DVec3| first_hit(&tris, ground, near, o, d);
        reference::inscatter_image(
            self.camera,
            w,
            h,
            distance,
            self.medium,
            self.light,
            occluders,
        )
    }

    /// The GPU image with `settings`, measured against `reference`.
    pub fn measure(
        &self,
        gpu: &HeadlessGpu,
        cache: &Cache,
        settings: MarchSettings,
        reference: &[DVec3],
    ) -> Measured {
        let (w, h) = self.size;
        let tris = self.scene.visible_triangles();
        let depths: Vec<f32> = (0..w * h)
            .map(|i| {
                let (o, d) = super::pixel_ray(self.camera, w, h, i % w, i / w);
                let ds = first_hit(&tris, self.scene.ground, near_plane(self.camera), o, d);
                if ds.is_finite() {
                    super::ndc_depth(self.camera, o + ds * d)
                } else {
                    self.camera.far_depth()
                }
            })
            .collect();
        let depth = super::depth_texture(gpu, w, h, &depths);
        let meshes: Vec<OccluderMesh> = self
            .scene
            .occluders
            .iter()
            .map(|o| OccluderMesh::new(&gpu.device, &o.mesh))
            .collect();
        let occluders: Vec<Occluder> = meshes
            .iter()
            .zip(&self.scene.occluders)
            .map(|(mesh, o)| Occluder {
                mesh,
                transform: o.transform,
            })
            .collect();
        let passes =
            super::ShadowPasses::new(self.camera, self.light, self.medium, &depth, &occluders)
                .settings(settings)
                .shadow_resolution(self.shadow_resolution)
                .filter(self.filter)
                .texture(self.texture.map(|(t, _)| t));
        let frame = super::shadow_frame(gpu, cache, &passes);
        let errors = errors(
            &frame.inscatter,
            reference,
            self.camera,
            self.light,
            self.size,
        );
        Measured {
            errors,
            frame,
            reference: reference.to_vec(),
        }
    }
}

/// A `&dyn LightSource` as a light source.
struct DynSource<'a>(&'a dyn LightSource);

impl LightSource for DynSource<'_> {
    fn light(&self) -> Light {
        self.0.light()
    }
    fn texture(&self) -> Option<&volshadow::scene::LightTexture> {
        self.0.texture()
    }
}
