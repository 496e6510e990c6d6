#import prelude.wgsl
#import clip.wgsl
// Shadow-volume extents node.
//
// 1. `reset` and `extrude` (compute): per occluder edge, a silhouette edge (one adjacent face
//    towards the light, one away) or an edge with a single face is extruded away from the light
//    to infinity (w = 0) as a quad; per triangle, light-facing ones form the front cap and the
//    others, projected to infinity, the back cap. Vertices are appended to a buffer whose count
//    is the vertex count of an indirect draw: no CPU readback.
// 2. Either three depth-only passes over those volumes, with the camera's view and a reversed-Z
//    infinite projection (depth = near / view depth): nearest front face, nearest back face,
//    farthest back face. Faces of open or non-manifold meshes count as back faces, which makes
//    their extents conservative (march from the eye, through the whole volume).
// 3. Or (exact mode) one pass that appends every face crossing in front of the scene surface
//    to a bounded per-pixel list (`fs_crossings`): between two consecutive crossings nothing
//    can change visibility, so the march integrates each interval in closed form.

struct DrawArgs {
    vertex_count: atomic<u32>,
    instance_count: u32,
    first_vertex: u32,
    first_instance: u32,
}

// Mirrors `VOLUME_VERTEX_BYTES` in src/nodes/extents.rs.
struct VolumeVertex {
    position: vec4<f32>,  // homogeneous world position, w = 0 at infinity
    flags: vec4<f32>,     // x = 1 for faces of an open or non-manifold mesh (conservative)
    // The face's plane: xyz its unit normal, w 1 if known (a finite plane: not the cap at
    // infinity, not degenerate), then a finite point of it. The exact mode intersects each
    // pixel's ray with it rather than trusting the rasteriser's interpolated depth, whose
    // precision is the GPU's (on an NVIDIA H200, crossings read from it were off by enough to
    // cost 100 times lavapipe's error where a light almost touches an occluder).
    plane: vec4<f32>,
    anchor: vec4<f32>,
}

// Mirrors `ExtrudeUniform` in src/nodes/extents.rs.
struct Extrude {
    world_from_object: mat4x4<f32>,
    light: Light,            // volumes extruded away from its position (a directional
                             // light: along its direction of travel)
    mirror: f32,             // −1 if the transform mirrors (flips the winding), else 1
    edges: u32,
    triangles: u32,
    closed: u32,             // 1 if the mesh is closed
    capacity: u32,           // volume vertices the buffer holds
}

@group(0) @binding(0) var<storage, read> ex: Extrude;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> indices: array<u32>;
@group(0) @binding(3) var<storage, read> edges: array<vec4<u32>>;
@group(0) @binding(4) var<storage, read_write> volume: array<VolumeVertex>;
@group(0) @binding(5) var<storage, read_write> args: DrawArgs;

@compute @workgroup_size(1)
fn reset() {
    atomicStore(&args.vertex_count, 0u);
    args.instance_count = 1u;
    args.first_vertex = 0u;
    args.first_instance = 0u;
}

fn world(i: u32) -> vec3<f32> {
    let p = ex.world_from_object * vec4<f32>(positions[i].xyz, 1.0);
    return p.xyz / p.w;
}

fn faces_light(face: u32) -> bool {
    let a = world(indices[3u * face]);
    let b = world(indices[3u * face + 1u]);
    let c = world(indices[3u * face + 2u]);
    let n = cross(b - a, c - a) * ex.mirror;
    return dot(n, towards_light(a)) > 0.0;
}

// From a point towards the light.
fn towards_light(a: vec3<f32>) -> vec3<f32> {
    if (ex.light.kind == LIGHT_DIRECTIONAL) {
        return -ex.light.position;
    }
    return ex.light.position - a;
}

// The plane through `anchor` with normal direction `n` (any length): its unit normal with w = 1,
// or w = 0 where `n` is zero or not finite. Scaled by its largest component before normalising,
// so that neither a tiny face's normal (whose squares would be subnormal, which a GPU may flush)
// nor a huge one's (whose squares would overflow) is lost.
fn plane_of(n: vec3<f32>) -> vec4<f32> {
    let m = max(abs(n.x), max(abs(n.y), abs(n.z)));
    if (!(m > 0.0) || !(m < 3.0e38)) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(normalize(n / m), 1.0);
}

fn emit(vertices: array<vec4<f32>, 6>, count: u32, plane: vec4<f32>, anchor: vec3<f32>) {
    let base = atomicAdd(&args.vertex_count, count);
    if (base + count > ex.capacity) {
        return; // cannot happen: capacity is sized for every edge and triangle
    }
    let conservative = select(1.0, 0.0, ex.closed == 1u);
    for (var k = 0u; k < count; k++) {
        volume[base + k].position = vertices[k];
        volume[base + k].flags = vec4<f32>(conservative, 0.0, 0.0, 0.0);
        volume[base + k].plane = plane;
        volume[base + k].anchor = vec4<f32>(anchor, 1.0);
    }
}

fn at_infinity(p: vec3<f32>) -> vec4<f32> {
    if (ex.light.kind == LIGHT_DIRECTIONAL) {
        // Every point goes to the same point at infinity: the volume is a prism along the
        // light's direction, and its cap at infinity is that point (nothing to draw).
        return vec4<f32>(ex.light.position, 0.0);
    }
    return vec4<f32>(p - ex.light.position, 0.0);
}

@compute @workgroup_size(64)
fn extrude(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    let edge_count = ex.edges;
    let tri_count = ex.triangles;
    if (i < edge_count) {
        let e = edges[i];
        let f0_lit = faces_light(e.z);
        var extrude_edge = true;
        var from_face0 = f0_lit;
        if (e.w != 0xffffffffu) {
            let f1_lit = faces_light(e.w);
            extrude_edge = f0_lit != f1_lit;
        }
        if (extrude_edge) {
            // Orient the quad by the light-facing side's winding so its outward normal points
            // out of the volume: edge a→b of the lit face gives (b, a, a∞) and (b, a∞, b∞).
            var a = world(e.x);
            var b = world(e.y);
            if (!from_face0) {
                let t = a;
                a = b;
                b = t;
            }
            let ai = at_infinity(a);
            let bi = at_infinity(b);
            // The quad's plane holds the edge and the direction away from the light at a.
            let plane = plane_of(cross(b - a, ai.xyz));
            emit(array<vec4<f32>, 6>(vec4<f32>(b, 1.0), vec4<f32>(a, 1.0), ai,
                                     vec4<f32>(b, 1.0), ai, bi), 6u, plane, a);
        }
    } else if (i < edge_count + tri_count) {
        let f = i - edge_count;
        var a = world(indices[3u * f]);
        var b = world(indices[3u * f + 1u]);
        let c = world(indices[3u * f + 2u]);
        if (ex.mirror < 0.0) {
            let t = a;
            a = b;
            b = t;
        }
        let zero = vec4<f32>(0.0);
        let lit = dot(cross(b - a, c - a), towards_light(a)) > 0.0;
        if (lit || ex.closed != 1u) {
            let plane = plane_of(cross(b - a, c - a));
            emit(array<vec4<f32>, 6>(vec4<f32>(a, 1.0), vec4<f32>(b, 1.0), vec4<f32>(c, 1.0), zero, zero, zero), 3u, plane, a);
        }
        if ((!lit || ex.closed != 1u) && ex.light.kind != LIGHT_DIRECTIONAL) {
            // At infinity: no finite plane; its fragments have depth 0.
            emit(array<vec4<f32>, 6>(at_infinity(a), at_infinity(b), at_infinity(c), zero, zero, zero), 3u, vec4<f32>(0.0), a);
        }
    }
}

// ---- rasterising the volumes ----

struct VolumeView {
    clip_from_world: mat4x4<f32>,   // reversed-Z infinite projection × camera view
}
@group(0) @binding(0) var<storage, read> vv: VolumeView;

struct VolumeOut {
    @builtin(position) position: vec4<f32>,
    @location(0) conservative: f32,
    @location(1) @interpolate(flat) plane: vec4<f32>,
    @location(2) @interpolate(flat) anchor: vec3<f32>,
}

@vertex
fn vs_volume(
    @location(0) position: vec4<f32>,
    @location(1) flags: vec4<f32>,
    @location(2) plane: vec4<f32>,
    @location(3) anchor: vec4<f32>,
) -> VolumeOut {
    var out: VolumeOut;
    out.position = vv.clip_from_world * position;
    out.conservative = flags.x;
    out.plane = plane;
    out.anchor = anchor.xyz;
    return out;
}

// The depth passes' view: each pixel's ray (binding 1, as the exact mode's `cross_view`).
@group(0) @binding(1) var<storage, read> cross_view: View;

// The fragment's depth: where the face's plane is known, that of the point where the pixel's
// centre ray meets it, to f32's precision rather than the rasteriser's (whose interpolated
// depth loses the face where a huge triangle is clipped: an occluder 1e8 wide 1.4 units above
// the eye); elsewhere (the cap at infinity) the rasterised one.
fn face_depth(in: VolumeOut) -> f32 {
    if (in.plane.w > 0.5) {
        let ray = pixel_ray(cross_view, in.position.xy, cross_view.far_depth);
        let eye = cross_view.world_from_view[3].xyz;
        let along = dot(in.plane.xyz, ray.dir);
        let t = dot(in.plane.xyz, in.anchor - eye) / along;
        if (abs(along) > 1.0e-6 && t > 0.0 && t < 3.0e38) {
            let clip = vv.clip_from_world * vec4<f32>(eye + ray.dir * t, 1.0);
            if (clip.w > 0.0) {
                return clamp(clip.z / clip.w, 0.0, 1.0);
            }
        }
    }
    return in.position.z;
}

// The volumes of an occluder far larger than its distance to the eye (see `ExtentsNode`'s
// `clips_volumes`): the rasteriser clips a triangle in f32, and where its finite vertices lie
// beyond about 2^24 times the depth of the clipped points (a roof 1e8 wide 1.4 units above the
// eye), the clipped polygon loses its place and pixels lose the face. So a triangle whose
// finite vertices reach farther from the eye than `VOLUME_CLIP_REACH` times its plane's
// distance is first clipped here, in homogeneous world coordinates (its vertices at infinity
// too), to a cube around the eye of that half-side, and drawn as the clipped polygon's fan:
// at most nine vertices, seven fan triangles, one per instance (`instance_index`), each
// invocation reading its whole triangle (`vertex_index` = 3 · triangle + corner). What is cut
// away lies farther than 4096 times the plane's distance, so its rays leave the eye within
// 1/4096 rad of the plane: a band a fraction of a pixel wide along the plane's horizon. Other
// triangles are drawn from their own vertices, as `vs_volume` draws them; a fan triangle the
// polygon does not have is degenerate outside the clip volume.
const VOLUME_CLIP_REACH: f32 = 4096.0;

@group(1) @binding(0) var<storage, read> clip_volume: array<VolumeVertex>;

@vertex
fn vs_volume_clipped(@builtin(vertex_index) v: u32, @builtin(instance_index) fan: u32)
    -> VolumeOut {
    let t = v / 3u;
    let corner = v - 3u * t;
    let first = clip_volume[3u * t];
    var out: VolumeOut;
    out.conservative = first.flags.x;
    out.plane = first.plane;
    out.anchor = first.anchor.xyz;
    let e = cross_view.world_from_view[3].xyz;
    var p: array<vec4<f32>, 9>;
    var far = 0.0;
    for (var c = 0u; c < 3u; c++) {
        p[c] = clip_volume[3u * t + c].position;
        if (p[c].w != 0.0) {
            far = max(far, max_abs(p[c].xyz / p[c].w - e));
        }
    }
    var n = 3u;
    let reach = VOLUME_CLIP_REACH * abs(dot(first.plane.xyz, first.anchor.xyz - e));
    if (first.plane.w > 0.5 && far > reach) {
        // Sutherland–Hodgman against `reach w - s (p - e w)[axis] >= 0`, six planes.
        var q: array<vec4<f32>, 9>;
        for (var plane = 0u; plane < 6u; plane++) {
            let axis = plane / 2u;
            let s = select(1.0, -1.0, (plane & 1u) == 1u);
            var m = 0u;
            for (var i = 0u; i < n; i++) {
                let a = p[i];
                let b = p[select(i + 1u, 0u, i + 1u == n)];
                let da = reach * a.w - s * (a[axis] - e[axis] * a.w);
                let db = reach * b.w - s * (b[axis] - e[axis] * b.w);
                if (da >= 0.0 && m < 9u) {
                    q[m] = a;
                    m++;
                }
                if ((da >= 0.0) != (db >= 0.0) && m < 9u) {
                    // From the edge's lesser end, so the triangle across the edge finds the
                    // same point, bit for bit: no crack between the two.
                    if (precedes(a, b)) {
                        q[m] = a + (b - a) * (da / (da - db));
                    } else {
                        q[m] = b + (a - b) * (db / (db - da));
                    }
                    m++;
                }
            }
            n = m;
            for (var i = 0u; i < n; i++) {
                p[i] = q[i];
            }
        }
    }
    if (fan + 2u >= n) {
        out.position = vec4<f32>(2.0, 2.0, 2.0, 1.0);
        return out;
    }
    let k = select(select(fan + 2u, fan + 1u, corner == 1u), 0u, corner == 0u);
    out.position = vv.clip_from_world * p[k];
    return out;
}

// Nearest front face: front faces of closed meshes only.
@fragment
fn fs_front(in: VolumeOut, @builtin(front_facing) front: bool) -> @builtin(frag_depth) f32 {
    if (!front || in.conservative > 0.5) {
        discard;
    }
    return face_depth(in);
}

// Nearest and farthest back face: back faces, and every face of an open mesh.
@fragment
fn fs_back(in: VolumeOut, @builtin(front_facing) front: bool) -> @builtin(frag_depth) f32 {
    if (front && in.conservative < 0.5) {
        discard;
    }
    return face_depth(in);
}

// ---- exact mode: every face crossing in front of the surface, per pixel ----

// Mirrors `CrossingUniform` in src/nodes/extents.rs.
struct CrossingParams {
    size: vec2<u32>,  // the pass size
    entries: u32,     // list entries per pixel (K)
    near: f32,        // the volumes' projection near plane (depth = near / view depth)
}

@group(0) @binding(2) var<storage, read> cp: CrossingParams;
@group(0) @binding(3) var cross_scene_depth: texture_depth_2d;
// Per pixel four u32: the crossing count in front of the surface (bit 31: a face of an open or
// non-manifold mesh crossed the pixel, so counting volumes is not meaningful there); the
// bitwise-not of the nearest crossing's bits and the farthest crossing's bits (positive f32
// bits order as the values do; zero-cleared, so "not" makes max a min); and the net number of
// volumes entered behind the surface (front faces +1, back faces −1, wrapping), which makes
// the number of volumes around every interval in front of it known (counted from the far end,
// as z-fail shadow volumes count, so faces cut by the near plane do not matter).
@group(0) @binding(4) var<storage, read_write> heads: array<atomic<u32>>;
// K signed view depths per pixel in arrival order (negative: a front face, entering a
// volume); entries past K are only counted.
@group(0) @binding(5) var<storage, read_write> crossings: array<f32>;

@fragment
fn fs_crossings(in: VolumeOut, @builtin(front_facing) front: bool) {
    let size = cp.size;
    let pix = vec2<u32>(in.position.xy);
    if (pix.x >= size.x || pix.y >= size.y) {
        return;
    }
    let p = pix.y * size.x + pix.x;
    if (in.conservative > 0.5) {
        atomicOr(&heads[4u * p], 0x80000000u);
    }
    // Entering a volume (a front face) adds one; leaving subtracts one.
    let step = select(0xffffffffu, 1u, front);
    let full = textureDimensions(cross_scene_depth);
    let under = min(vec2<u32>((vec2<f32>(pix) + 0.5) * vec2<f32>(full) / vec2<f32>(size)), full - 1u);
    let ray = pixel_ray(cross_view, vec2<f32>(pix) + 0.5, textureLoad(cross_scene_depth, under, 0));
    // Depth 0 is at infinity (the dark cap, the far ends of the sides): behind everything.
    var behind = !(in.position.z > 0.0);
    var z = cp.near / max(in.position.z, 1.0e-38);
    // Where the face's plane is known, the crossing is where the pixel's centre ray meets it
    // (the point the rasteriser sampled), to f32's precision rather than the rasteriser's.
    if (in.plane.w > 0.5) {
        let eye = cross_view.world_from_view[3].xyz;
        let along = dot(in.plane.xyz, ray.dir);
        let exact_z = dot(in.plane.xyz, in.anchor - eye) / (along * ray.depth_to_distance);
        if (abs(along) > 1.0e-6 && exact_z > 0.0 && exact_z < 3.0e38) {
            z = exact_z;
            behind = false;
        }
    }
    if (!behind) {
        behind = ray.distance >= 0.0 && z * ray.depth_to_distance >= ray.distance;
    }
    if (behind) {
        // Cannot shadow this pixel's medium: only counted.
        atomicAdd(&heads[4u * p + 3u], step);
        return;
    }
    let bits = bitcast<u32>(z);
    atomicMax(&heads[4u * p + 1u], ~bits);
    atomicMax(&heads[4u * p + 2u], bits);
    let i = atomicAdd(&heads[4u * p], 1u) & 0x7fffffffu;
    if (i < cp.entries) {
        crossings[cp.entries * p + i] = select(z, -z, front);
    }
}
