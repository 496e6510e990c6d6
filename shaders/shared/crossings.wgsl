#import prelude.wgsl
// Shadow-volume crossing lists built in compute (the exact method's default build).
//
// Per pixel, every shadow-volume face its centre ray crosses: the view depth of each crossing
// in front of the scene surface (a bounded list), the nearest and farthest of them, and the net
// number of volumes entered behind the surface. The output is the fragment build's
// (`fs_crossings` in extents.wgsl), read by the march unchanged.
//
// A face covers a pixel when the pixel's ray from the eye passes through it: with the face's
// vertices taken relative to the eye (homogeneous: a vertex at infinity is its direction), the
// ray's direction d is inside the cone they span, which is three signs of det(P, Q, d), one per
// edge (P, Q). No near-plane clipping and no projection is involved, so faces through or behind
// the eye and faces at infinity need no special case. The test is watertight: the two faces
// sharing an edge compute det for it from the same canonically ordered pair of vertices and the
// same expression, so their values are exact negatives whatever the GPU's rounding or fused
// multiply-adds, and a ray exactly on the edge (det = 0) is given to one of the two by the
// canonical order.
//
// Passes (all compute, recorded every frame, no CPU readback):
//   1. `setup`, one invocation per face: the face's edge functions, plane, depth range and
//      screen bounding box (16 × 16 pixel tiles), after clipping at the near plane.
//   2. `count`, a workgroup per face (strided): its tiles' counters, a tile being skipped when
//      one edge has all four of the tile's corner rays strictly outside (for a perspective
//      projection, an edge function is affine in pixel coordinates: one evaluation, at the
//      corner its gradient points to).
//   3. `scan`, one workgroup: each tile's offset into the bin array.
//   4. `fill`, as `count`: each tile's list of faces.
//   5. `crossings`, a workgroup per tile: every pixel tests its ray against the tile's faces,
//      loaded 256 at a time into workgroup memory.
// A tile whose list would not fit the bin array tests every face instead (correct, slower).

const TILE: u32 = 16u;
const CHUNK: u32 = 256u;
// Strided workgroups of `count` and `fill`.
const GROUPS: u32 = 1024u;

// Face flags (the first vec4's w).
const TIE0: u32 = 1u;          // a ray exactly on edge 0 (det = 0) counts as inside; 2, 4: edges 1, 2
const FRONT: u32 = 8u;         // entering the volume (a front face)
const CONSERVATIVE: u32 = 16u; // a face of an open or non-manifold mesh
const AT_INFINITY: u32 = 32u;  // every vertex at infinity: behind everything
const VALID: u32 = 64u;        // covers some pixel

// Mirrors `BinUniform` in src/nodes/extents.rs.
struct Params {
    view_from_clip: mat4x4<f32>,      // the camera at the pass size (`View`, see `bin_view`)
    world_from_view: mat4x4<f32>,
    clip_from_world: mat4x4<f32>,     // the extents' reversed-Z infinite projection × view
    view_size: vec2<f32>,             // the camera's `View::size`
    size: vec2<u32>,                  // the pass size
    tiles: vec2<u32>,                 // tiles across and down
    far_depth: f32,                   // the camera's `View::far_depth`
    entries: u32,                     // list entries per pixel (K)
    near: f32,                        // crossings nearer than this view depth are not counted
    bin_capacity: u32,                // entries of `bins`
    face_capacity: u32,               // faces `faces` holds
    affine: u32,                      // 1: a ray's direction is affine in its pixel coordinates
}

// Mirrors `DrawArgs` in extents.wgsl: the volume's vertex count.
struct Count {
    vertex_count: u32,
    instance_count: u32,
    first_vertex: u32,
    first_instance: u32,
}

// The volume: 4 vec4 per vertex (position, flags, plane, anchor; `VolumeVertex` in
// extents.wgsl), 3 vertices per face.
@group(0) @binding(0) var<storage, read> volume: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read> count_args: Count;
@group(0) @binding(2) var<storage, read> bp: Params;
@group(0) @binding(3) var scene_depth: texture_depth_2d;
// Per face 5 vec4: (edge 0's normal, meta), (edge 1's, tile box min packed), (edge 2's, tile
// box max packed), (the plane's unit normal, its signed distance from the eye),
// (nearest and farthest view depth of the face, 0, 0).
@group(0) @binding(4) var<storage, read_write> faces: array<vec4<f32>>;
// Per tile: count, offset, cursor (3 arrays of `tiles.x * tiles.y`), then the bins in use.
@group(0) @binding(5) var<storage, read_write> tiles: array<atomic<u32>>;
// The same, for the passes that need no atomics (`scan` and `build`: plain loads and stores
// are several times cheaper than atomics on some GPUs).
@group(0) @binding(5) var<storage, read_write> tiles_plain: array<u32>;
@group(0) @binding(6) var<storage, read_write> bins: array<u32>;
// The lists, as the fragment build writes them (see extents.wgsl).
@group(0) @binding(7) var<storage, read_write> heads: array<u32>;
@group(0) @binding(8) var<storage, read_write> crossings: array<f32>;

// The camera at the pass size.
fn bin_view() -> View {
    return View(bp.view_from_clip, bp.world_from_view, bp.view_size, bp.far_depth);
}

fn face_count() -> u32 {
    return min(count_args.vertex_count / 3u, bp.face_capacity);
}

fn tile_count() -> u32 {
    return bp.tiles.x * bp.tiles.y;
}

fn eye() -> vec3<f32> {
    return bp.world_from_view[3].xyz;
}

// A homogeneous point relative to the eye: a finite point's offset, or a direction at infinity.
fn rel(p: vec4<f32>) -> vec3<f32> {
    if (p.w == 0.0) {
        return p.xyz;
    }
    return p.xyz - eye();
}

// Lexicographic order of two vertices (the canonical order of an edge).
fn before(a: vec4<f32>, b: vec4<f32>) -> bool {
    if (a.x != b.x) { return a.x < b.x; }
    if (a.y != b.y) { return a.y < b.y; }
    if (a.z != b.z) { return a.z < b.z; }
    return a.w < b.w;
}

// The edge function of edge (p, q) from the canonical pair: cross(lo, hi), and +1 if p is lo.
fn edge_normal(p: vec4<f32>, q: vec4<f32>) -> vec4<f32> {
    if (before(q, p)) {
        return vec4<f32>(cross(rel(q), rel(p)), -1.0);
    }
    return vec4<f32>(cross(rel(p), rel(q)), 1.0);
}

// The direction (unnormalised, world space) of the ray through pixel coordinates `px`.
fn ray_dir(px: vec2<f32>) -> vec3<f32> {
    let v = bin_view();
    let ndc = vec2<f32>(px.x / v.size.x * 2.0 - 1.0, 1.0 - px.y / v.size.y * 2.0);
    let near_h = v.view_from_clip * vec4<f32>(ndc, 1.0 - v.far_depth, 1.0);
    let m = mat3x3<f32>(v.world_from_view[0].xyz, v.world_from_view[1].xyz, v.world_from_view[2].xyz);
    return m * (near_h.xyz / near_h.w);
}

@compute @workgroup_size(64)
fn setup(@builtin(global_invocation_id) gid: vec3<u32>,
         @builtin(num_workgroups) groups: vec3<u32>) {
    let f = gid.x + gid.y * groups.x * 64u;
    if (f >= face_count()) {
        return;
    }
    faces[5u * f] = vec4<f32>(0.0); // not valid until shown otherwise
    let base = 12u * f;
    let pa = volume[base];
    let pb = volume[base + 4u];
    let pc = volume[base + 8u];
    let flags = volume[base + 1u];
    let plane = volume[base + 2u];
    let anchor = volume[base + 3u];
    // The orientation seen from the eye: det < 0 when the eye is on the side the face's
    // outward normal points to, a face entering the volume.
    let det = dot(rel(pa), cross(rel(pb), rel(pc)));
    if (!(abs(det) > 0.0) || !(abs(det) < 3.0e38)) {
        return; // edge-on from the eye, or degenerate: covers no pixel
    }
    let s = sign(det);
    let e = array<vec4<f32>, 3>(edge_normal(pa, pb), edge_normal(pb, pc), edge_normal(pc, pa));
    var bits = VALID;
    for (var k = 0u; k < 3u; k++) {
        if (s * e[k].w > 0.0) {
            bits |= TIE0 << k;
        }
    }
    if (s < 0.0) {
        bits |= FRONT;
    }
    if (flags.x > 0.5) {
        bits |= CONSERVATIVE;
    }
    let infinite = pa.w == 0.0 && pb.w == 0.0 && pc.w == 0.0;
    if (infinite) {
        bits |= AT_INFINITY;
    }

    // View depths of the vertices (a direction pointing ahead is infinitely far).
    let fwd = -bp.world_from_view[2].xyz;
    var z_lo = 3.0e38;
    var z_hi = 0.0;
    for (var k = 0u; k < 3u; k++) {
        let p = volume[base + 4u * k];
        let z = dot(rel(p), fwd) / dot(fwd, fwd);
        var zk = z;
        if (p.w == 0.0) {
            zk = select(-1.0, 3.0e38, z > 0.0);
        }
        z_lo = min(z_lo, zk);
        z_hi = max(z_hi, zk);
    }
    if (z_hi < bp.near) {
        return; // wholly nearer than the near plane
    }

    // The screen box of the part beyond the near plane (clip z ≤ w): clip the triangle there
    // (at most 4 vertices remain), then project.
    var lo = vec2<f32>(3.0e38);
    var hi = vec2<f32>(-3.0e38);
    var everywhere = false;
    var clip: array<vec4<f32>, 3>;
    for (var k = 0u; k < 3u; k++) {
        clip[k] = bp.clip_from_world * volume[base + 4u * k];
    }
    for (var k = 0u; k < 3u; k++) {
        let c0 = clip[k];
        let c1 = clip[(k + 1u) % 3u];
        let d0 = c0.w - c0.z;
        let d1 = c1.w - c1.z;
        var pts: array<vec4<f32>, 2>;
        var n = 0u;
        if (d0 >= 0.0) {
            pts[n] = c0;
            n++;
        }
        if ((d0 >= 0.0) != (d1 >= 0.0)) {
            pts[n] = mix(c0, c1, d0 / (d0 - d1));
            n++;
        }
        for (var j = 0u; j < n; j++) {
            let c = pts[j];
            if (!(c.w > 1.0e-30 * max(abs(c.x), abs(c.y)))) {
                everywhere = true; // projects to infinity (or nowhere): no useful box
            } else {
                let ndc = c.xy / c.w;
                let px = vec2<f32>((ndc.x * 0.5 + 0.5) * bp.view_size.x,
                                   (0.5 - ndc.y * 0.5) * bp.view_size.y);
                lo = min(lo, px);
                hi = max(hi, px);
            }
        }
    }
    let size = vec2<f32>(bp.size);
    if (everywhere) {
        lo = vec2<f32>(0.0);
        hi = size;
    }
    // One pixel of margin for the rounding of the projection (the tiles' corner tests decide).
    lo = max(lo - 1.0, vec2<f32>(0.0));
    hi = min(hi + 1.0, size - 1.0);
    if (!(lo.x <= hi.x) || !(lo.y <= hi.y)) {
        return; // off screen
    }
    let t0 = vec2<u32>(lo) / TILE;
    let t1 = min(vec2<u32>(hi) / TILE, bp.tiles - 1u);
    faces[5u * f] = vec4<f32>(s * e[0].w * e[0].xyz, bitcast<f32>(bits));
    faces[5u * f + 1u] = vec4<f32>(s * e[1].w * e[1].xyz, bitcast<f32>(t0.x | (t0.y << 16u)));
    faces[5u * f + 2u] = vec4<f32>(s * e[2].w * e[2].xyz, bitcast<f32>(t1.x | (t1.y << 16u)));
    // The plane (unit normal, w = 1 if known) as its signed distance from the eye.
    var n = vec4<f32>(0.0);
    if (plane.w > 0.5) {
        n = vec4<f32>(plane.xyz, dot(plane.xyz, anchor.xyz - eye()));
    }
    faces[5u * f + 3u] = n;
    faces[5u * f + 4u] = vec4<f32>(max(z_lo, 0.0), z_hi, plane.w, 0.0);
}

// Whether face `f`'s edges leave some of tile `t`'s corner rays inside (conservative).
fn tile_touches(e0: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>, t: vec2<u32>) -> bool {
    let a = vec2<f32>(t * TILE);
    let b = min(a + f32(TILE), vec2<f32>(bp.size));
    let d = array<vec3<f32>, 4>(ray_dir(a), ray_dir(vec2<f32>(b.x, a.y)), ray_dir(vec2<f32>(a.x, b.y)), ray_dir(b));
    let e = array<vec3<f32>, 3>(e0, e1, e2);
    for (var k = 0u; k < 3u; k++) {
        var outside = true;
        for (var c = 0u; c < 4u; c++) {
            // A margin relative to the operands covers the rounding of the corner rays.
            outside = outside && dot(e[k], d[c]) < -1.0e-5 * length(e[k]) * length(d[c]);
        }
        if (outside) {
            return false;
        }
    }
    return true;
}

// An edge function as an affine function of pixel coordinates (valid when `bp.affine` is 1:
// the inverse projection's w row has no x or y term, as for every perspective projection):
// value at pixel (0, 0), change per pixel across and down, and the margin within which the
// rounding of the two evaluations may disagree.
fn edge_plane(e: vec3<f32>, d0: vec3<f32>, dx: vec3<f32>, dy: vec3<f32>) -> vec4<f32> {
    let size = vec2<f32>(bp.size);
    return vec4<f32>(dot(e, d0), dot(e, dx) / size.x, dot(e, dy) / size.y,
                     1.0e-5 * length(e) * (length(d0) + length(dx) + length(dy)));
}

// Whether some point of tile `t` is not strictly outside any of the three edge planes: each is
// affine, so its largest value over the tile is at the corner its gradient points to.
fn tile_touches_affine(planes: array<vec4<f32>, 3>, t: vec2<u32>) -> bool {
    let a = vec2<f32>(t * TILE);
    let b = min(a + f32(TILE), vec2<f32>(bp.size));
    for (var k = 0u; k < 3u; k++) {
        let e = planes[k];
        let x = select(a.x, b.x, e.y > 0.0);
        let y = select(a.y, b.y, e.z > 0.0);
        if (e.x + e.y * x + e.z * y < -e.w) {
            return false;
        }
    }
    return true;
}

fn unpack_tile(bits: f32) -> vec2<u32> {
    let u = bitcast<u32>(bits);
    return vec2<u32>(u & 0xffffu, u >> 16u);
}

// `count` and `fill`: each workgroup takes faces GROUPS apart; its invocations split the face's
// tiles.
fn bin_faces(group: u32, local: u32, fill: bool) {
    let n = face_count();
    let tn = tile_count();
    let d0 = ray_dir(vec2<f32>(0.0));
    let dx = ray_dir(vec2<f32>(f32(bp.size.x), 0.0)) - d0;
    let dy = ray_dir(vec2<f32>(0.0, f32(bp.size.y))) - d0;
    for (var f = group; f < n; f += GROUPS) {
        let f0 = faces[5u * f];
        if ((bitcast<u32>(f0.w) & VALID) == 0u) {
            continue;
        }
        let f1 = faces[5u * f + 1u];
        let f2 = faces[5u * f + 2u];
        let t0 = unpack_tile(f1.w);
        let t1 = unpack_tile(f2.w);
        let w = t1.x - t0.x + 1u;
        let total = w * (t1.y - t0.y + 1u);
        let planes = array<vec4<f32>, 3>(edge_plane(f0.xyz, d0, dx, dy),
                                         edge_plane(f1.xyz, d0, dx, dy),
                                         edge_plane(f2.xyz, d0, dx, dy));
        for (var i = local; i < total; i += 64u) {
            let t = t0 + vec2<u32>(i % w, i / w);
            var touches: bool;
            if (bp.affine == 1u) {
                touches = tile_touches_affine(planes, t);
            } else {
                touches = tile_touches(f0.xyz, f1.xyz, f2.xyz, t);
            }
            if (touches) {
                let ti = t.y * bp.tiles.x + t.x;
                if (fill) {
                    let at = atomicLoad(&tiles[tn + ti]) + atomicAdd(&tiles[2u * tn + ti], 1u);
                    if (at < bp.bin_capacity) {
                        bins[at] = f;
                    }
                } else {
                    atomicAdd(&tiles[ti], 1u);
                }
            }
        }
    }
}

@compute @workgroup_size(64)
fn count(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) local: u32) {
    bin_faces(wg.x, local, false);
}

@compute @workgroup_size(64)
fn fill(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) local: u32) {
    bin_faces(wg.x, local, true);
}

var<workgroup> partial: array<u32, 256>;

// Exclusive prefix sum of the tiles' counts into their offsets, by one workgroup: each
// invocation sums a run of tiles, the runs' sums are scanned, then each run is written.
@compute @workgroup_size(256)
fn scan(@builtin(local_invocation_index) local: u32) {
    let tn = tile_count();
    let run = (tn + 255u) / 256u;
    let first = min(local * run, tn);
    let last = min(first + run, tn);
    var sum = 0u;
    for (var i = first; i < last; i++) {
        sum += tiles_plain[i];
    }
    partial[local] = sum;
    workgroupBarrier();
    for (var step = 1u; step < 256u; step *= 2u) {
        var v = 0u;
        if (local >= step) {
            v = partial[local - step];
        }
        workgroupBarrier();
        partial[local] += v;
        workgroupBarrier();
    }
    var at = partial[local] - sum;
    for (var i = first; i < last; i++) {
        tiles_plain[tn + i] = at;
        at += tiles_plain[i];
    }
}

var<workgroup> chunk0: array<vec4<f32>, CHUNK>;
var<workgroup> chunk1: array<vec4<f32>, CHUNK>;
var<workgroup> chunk2: array<vec4<f32>, CHUNK>;
var<workgroup> tile_range: vec2<u32>; // the tile's first bin and its face count
var<workgroup> tile_all: u32;         // 1: the tile's list did not fit, test every face

fn inside(v: f32, tie: bool) -> bool {
    return v > 0.0 || (v == 0.0 && tie);
}

@compute @workgroup_size(16, 16)
fn build(@builtin(workgroup_id) wg: vec3<u32>,
         @builtin(local_invocation_id) lid: vec3<u32>,
         @builtin(local_invocation_index) local: u32) {
    let tn = tile_count();
    let ti = wg.y * bp.tiles.x + wg.x;
    if (local == 0u) {
        let n = tiles_plain[ti];
        let at = tiles_plain[tn + ti];
        tile_all = select(0u, 1u, at + n > bp.bin_capacity);
        tile_range = vec2<u32>(at, n);
    }
    let every_face = workgroupUniformLoad(&tile_all) == 1u;
    var range = workgroupUniformLoad(&tile_range);
    if (every_face) {
        range = vec2<u32>(0u, face_count());
    }

    let size = bp.size;
    let pix = wg.xy * TILE + lid.xy;
    let on = pix.x < size.x && pix.y < size.y;
    let p = pix.y * size.x + pix.x;
    let full = textureDimensions(scene_depth);
    let pc = min(pix, size - 1u);
    let under = min(vec2<u32>((vec2<f32>(pc) + 0.5) * vec2<f32>(full) / vec2<f32>(size)), full - 1u);
    let ray = pixel_ray(bin_view(), vec2<f32>(pc) + 0.5, textureLoad(scene_depth, under, 0));
    let d = ray.dir;

    var n_front = 0u;
    var open = 0u;
    var z_min = 3.0e38;
    var z_max = 0.0;
    var net = 0u;
    for (var first = 0u; first < range.y; first += CHUNK) {
        let m = min(CHUNK, range.y - first);
        if (local < m) {
            var f = first + local;
            if (!every_face) {
                f = bins[range.x + f];
            }
            chunk0[local] = faces[5u * f];
            chunk1[local] = faces[5u * f + 1u];
            chunk2[local] = vec4<f32>(faces[5u * f + 2u].xyz, bitcast<f32>(f));
        }
        workgroupBarrier();
        for (var j = 0u; j < m; j++) {
            let c0 = chunk0[j];
            let bits = bitcast<u32>(c0.w);
            let c1 = chunk1[j];
            let c2 = chunk2[j];
            if ((bits & VALID) == 0u
                || !inside(dot(c0.xyz, d), (bits & TIE0) != 0u)
                || !inside(dot(c1.xyz, d), (bits & (TIE0 << 1u)) != 0u)
                || !inside(dot(c2.xyz, d), (bits & (TIE0 << 2u)) != 0u)) {
                continue;
            }
            let f = bitcast<u32>(c2.w);
            let front = (bits & FRONT) != 0u;
            // Entering a volume adds one, leaving subtracts one.
            let step = select(0xffffffffu, 1u, front);
            if ((bits & AT_INFINITY) != 0u) {
                // The dark cap at infinity: behind everything.
                open |= bits & CONSERVATIVE;
                net += step;
                continue;
            }
            let plane = faces[5u * f + 3u];
            let range_z = faces[5u * f + 4u];
            if (range_z.z < 0.5) {
                continue; // no finite plane and not at infinity: degenerate
            }
            // Where the ray meets the face's plane, kept within the face's own depth range
            // (a ray almost in the plane has an ill-conditioned intersection).
            var z = plane.w / (dot(plane.xyz, d) * ray.depth_to_distance);
            if (!(z >= range_z.x)) {
                z = range_z.x;
            }
            z = min(z, range_z.y);
            if (z < bp.near) {
                continue; // nearer than the near plane: the fragment build's clipping
            }
            open |= bits & CONSERVATIVE;
            if (!(z < 3.0e38) || (ray.distance >= 0.0 && z * ray.depth_to_distance >= ray.distance)) {
                net += step; // cannot shadow this pixel's medium: only counted
                continue;
            }
            z_min = min(z_min, z);
            z_max = max(z_max, z);
            if (on && n_front < bp.entries) {
                crossings[bp.entries * p + n_front] = select(z, -z, front);
            }
            n_front++;
        }
        workgroupBarrier();
    }
    if (!on) {
        return;
    }
    var head = vec4<u32>(n_front, 0u, 0u, net);
    if (open != 0u) {
        head.x |= 0x80000000u;
    }
    if (n_front > 0u) {
        head.y = ~bitcast<u32>(z_min);
        head.z = bitcast<u32>(z_max);
    }
    heads[4u * p] = head.x;
    heads[4u * p + 1u] = head.y;
    heads[4u * p + 2u] = head.z;
    heads[4u * p + 3u] = head.w;
}
