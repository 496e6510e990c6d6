// The shadow map's gate (an exact-method light without a radius): the map is drawn only if a
// pixel's crossings cannot decide its visibility by counting volumes, that is, if its list
// overflowed or a face of an open or non-manifold mesh crossed it (the march looks those
// pixels up in the map). Scans the crossing heads; the first workgroup that finds such a pixel
// copies the map's draw arguments (the clears and the occluders' draws, written by the CPU) into
// the arguments its indirect draws read, which are otherwise zero: nothing is drawn.

// Mirrors `GateUniform` in src/nodes/shadow_map.rs.
struct GateParams {
    pixels: u32,   // pixels of the crossing lists
    entries: u32,  // entries per pixel
    words: u32,    // u32 words of the draw arguments
    pad: u32,
}

// Per pixel four u32 (`shaders/passes/extents.wgsl`): the first is the crossing count, bit 31 set
// where an open or non-manifold mesh's face crossed the pixel.
@group(0) @binding(0) var<storage, read> heads: array<u32>;
@group(0) @binding(1) var<storage, read> arguments: array<u32>;
@group(0) @binding(2) var<storage, read> gp: GateParams;
// [0]: the map has been drawn since its inputs last changed (the CPU clears it then);
// [1]: this frame draws it (cleared every frame; read by benches and tests).
@group(0) @binding(3) var<storage, read_write> gate: array<atomic<u32>, 2>;
@group(0) @binding(4) var<storage, read_write> live: array<u32>;

var<workgroup> flagged: atomic<u32>;

@compute @workgroup_size(256)
fn scan(@builtin(workgroup_id) wg: vec3<u32>,
        @builtin(num_workgroups) groups: vec3<u32>,
        @builtin(local_invocation_index) local: u32) {
    let p = (wg.y * groups.x + wg.x) * 256u + local;
    if (p < gp.pixels) {
        let head = heads[4u * p];
        if ((head & 0x80000000u) != 0u || (head & 0x7fffffffu) > gp.entries) {
            atomicOr(&flagged, 1u);
        }
    }
    workgroupBarrier();
    if (local == 0u && atomicLoad(&flagged) != 0u) {
        if (atomicOr(&gate[0], 1u) == 0u) {
            for (var i = 0u; i < gp.words; i++) {
                live[i] = arguments[i];
            }
            atomicStore(&gate[1], 1u);
        }
    }
}
