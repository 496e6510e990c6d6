//! A bounding volume hierarchy over the triangles of a reference
//! [`TriangleMesh`](super::TriangleMesh): axis-aligned boxes, binned surface-area heuristic, a
//! flat depth-first node array.
//!
//! It only *culls*: whatever a caller decides for a triangle (the Möller–Trumbore test, a plane
//! crossing) is computed from the same vertex values as without it. So the boxes are padded
//! and the segment/ray–box tests have slack, enough that a triangle the exact test could accept
//! (with its rounding) is never culled; the hierarchy then changes the cost, not the answers.

use glam::DVec3;

/// A triangle as its first vertex and two edge vectors, `e1 = v1 − v0`, `e2 = v2 − v0` (the
/// same subtractions the triangle tests would otherwise do per call).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Triangle {
    pub v0: DVec3,
    pub e1: DVec3,
    pub e2: DVec3,
}

impl Triangle {
    pub fn new([v0, v1, v2]: [DVec3; 3]) -> Self {
        Self {
            v0,
            e1: v1 - v0,
            e2: v2 - v0,
        }
    }
}

/// Triangles per leaf, at most (unless all centroids coincide and the split is arbitrary).
const LEAF_SIZE: usize = 4;
/// Bins of the surface-area heuristic.
const BINS: usize = 16;
/// Depth beyond which nodes are split at the median (bounds the depth, so that a fixed
/// traversal stack suffices: the median split adds at most 32 levels).
const SAH_DEPTH: usize = 64;
const STACK: usize = 128;

/// Relative padding of every triangle's box: of its own extent (covers the rounding of the
/// barycentric tests of thin triangles) and of its coordinates' magnitude (the rounding of
/// the box test itself).
const PAD_EXTENT: f64 = 1e-7;
const PAD_MAGNITUDE: f64 = 1e-12;
/// Slack of a segment's parameter range `[0, 1]` and of a ray's start, in units of the
/// segment length or of the ray's distance scale.
const PARAM_SLACK: f64 = 1e-7;

#[derive(Debug, Clone, Copy)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: first triangle. Internal: the second child (the first child is the next node).
    index: u32,
    /// Triangles in a leaf; 0 for an internal node.
    count: u32,
}

#[derive(Debug, Clone, Copy)]
struct Item {
    lo: DVec3,
    hi: DVec3,
    centroid: DVec3,
    triangle: Triangle,
}

/// The hierarchy: nodes in depth-first order (root first) and the triangles, reordered so that
/// each leaf's are contiguous.
#[derive(Debug, Clone, Default)]
pub(super) struct Bvh {
    nodes: Vec<Node>,
    triangles: Vec<Triangle>,
}

fn area(lo: DVec3, hi: DVec3) -> f64 {
    let d = (hi - lo).max(DVec3::ZERO);
    d.x * d.y + d.y * d.z + d.z * d.x
}

impl Bvh {
    /// A hierarchy over the triangles with finite vertices (a triangle with a non-finite vertex
    /// is never hit by the Möller–Trumbore test and has no crossing: it is left out).
    pub fn new(triangles: impl IntoIterator<Item = [DVec3; 3]>) -> Self {
        let mut items: Vec<Item> = triangles
            .into_iter()
            .filter(|t| t.iter().all(|p| p.is_finite()))
            .map(|t| {
                let lo = t[0].min(t[1]).min(t[2]);
                let hi = t[0].max(t[1]).max(t[2]);
                let pad = PAD_EXTENT * (hi - lo).max_element()
                    + PAD_MAGNITUDE * lo.abs().max(hi.abs()).max_element()
                    + f64::MIN_POSITIVE;
                Item {
                    lo: lo - DVec3::splat(pad),
                    hi: hi + DVec3::splat(pad),
                    centroid: 0.5 * (lo + hi),
                    triangle: Triangle::new(t),
                }
            })
            .collect();
        let mut bvh = Self {
            nodes: Vec::with_capacity(2 * items.len() / LEAF_SIZE + 1),
            triangles: Vec::with_capacity(items.len()),
        };
        if !items.is_empty() {
            bvh.build(&mut items, 0);
        }
        bvh
    }

    /// Appends the node for `items` (and its subtree); returns its index.
    fn build(&mut self, items: &mut [Item], depth: usize) -> usize {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        let (mut clo, mut chi) = (lo, hi);
        for item in items.iter() {
            lo = lo.min(item.lo);
            hi = hi.max(item.hi);
            clo = clo.min(item.centroid);
            chi = chi.max(item.centroid);
        }
        let index = self.nodes.len();
        self.nodes.push(Node {
            lo,
            hi,
            index: 0,
            count: 0,
        });
        let extent = chi - clo;
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        if items.len() <= LEAF_SIZE || !(extent[axis] > 0.0) {
            self.nodes[index].index = self.triangles.len() as u32;
            self.nodes[index].count = items.len() as u32;
            self.triangles.extend(items.iter().map(|i| i.triangle));
            return index;
        }
        let mid = if depth < SAH_DEPTH {
            sah_split(items, axis, clo[axis], extent[axis])
        } else {
            None
        }
        .unwrap_or_else(|| {
            let mid = items.len() / 2;
            items.select_nth_unstable_by(mid, |a, b| a.centroid[axis].total_cmp(&b.centroid[axis]));
            mid
        });
        let (left, right) = items.split_at_mut(mid);
        self.build(left, depth + 1);
        let second = self.build(right, depth + 1);
        self.nodes[index].index = second as u32;
        index
    }

    /// Visits the triangles whose boxes the segment from `o` along `d`, parameters
    /// `[t0, t1]`, may meet, until `visit` returns `true`; returns whether it did.
    fn traverse(
        &self,
        o: DVec3,
        d: DVec3,
        t0: f64,
        t1: f64,
        mut visit: impl FnMut(&Triangle) -> bool,
    ) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let inv = d.recip();
        let flat = d.cmpeq(DVec3::ZERO);
        let hits = |node: &Node| {
            let (mut near, mut far) = (t0, t1);
            for k in 0..3 {
                if flat.test(k) {
                    if o[k] < node.lo[k] || o[k] > node.hi[k] {
                        return false;
                    }
                    continue;
                }
                let a = (node.lo[k] - o[k]) * inv[k];
                let b = (node.hi[k] - o[k]) * inv[k];
                near = near.max(a.min(b));
                far = far.min(a.max(b));
            }
            // `!(near > far)` also lets NaN through: culling must never be wrong.
            !(near > far)
        };
        let mut stack = [0u32; STACK];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if !hits(node) {
                continue;
            }
            if node.count > 0 {
                let first = node.index as usize;
                for triangle in &self.triangles[first..first + node.count as usize] {
                    if visit(triangle) {
                        return true;
                    }
                }
            } else {
                stack[top] += 1; // the first child
                stack[top + 1] = node.index;
                top += 2;
            }
        }
        false
    }

    /// Whether `hit` accepts any triangle whose box the closed segment `[a, b]` may meet
    /// (stops at the first).
    pub fn any_on_segment(&self, a: DVec3, b: DVec3, hit: impl FnMut(&Triangle) -> bool) -> bool {
        self.traverse(a, b - a, -PARAM_SLACK, 1.0 + PARAM_SLACK, hit)
    }

    /// Whether `hit` accepts any triangle whose box the half-line `e + s·d`, `s ≥ 0`, may meet
    /// (stops at the first).
    pub fn any_on_ray(&self, e: DVec3, d: DVec3, hit: impl FnMut(&Triangle) -> bool) -> bool {
        self.traverse(e, d, -PARAM_SLACK, f64::INFINITY, hit)
    }

    /// Visits every triangle whose box the ray `e + x·v`, `x ≥ 0`, may meet.
    pub fn each_on_ray(&self, e: DVec3, v: DVec3, mut visit: impl FnMut(&Triangle)) {
        // The slack before the start is relative to the ray's distance scale (`v` is unit).
        let start = -PARAM_SLACK * (1.0 + e.abs().max_element());
        self.traverse(e, v, start, f64::INFINITY, |t| {
            visit(t);
            false
        });
    }
}

/// The binned surface-area split of `items` along `axis` (centroids in `[lo, lo + extent]`):
/// partitions `items` and returns the size of the first part, or `None` if no bin boundary
/// separates them.
fn sah_split(items: &mut [Item], axis: usize, lo: f64, extent: f64) -> Option<usize> {
    let scale = BINS as f64 / extent;
    let bin = |c: f64| (((c - lo) * scale) as usize).min(BINS - 1);
    let empty = (
        DVec3::splat(f64::INFINITY),
        DVec3::splat(f64::NEG_INFINITY),
        0usize,
    );
    let mut bins = [empty; BINS];
    for item in items.iter() {
        let b = &mut bins[bin(item.centroid[axis])];
        b.0 = b.0.min(item.lo);
        b.1 = b.1.max(item.hi);
        b.2 += 1;
    }
    // Costs of the splits after bin i: areas × counts of the two sides.
    let mut right_cost = [0.0; BINS];
    let (mut rlo, mut rhi, mut rn) = empty;
    for i in (1..BINS).rev() {
        rlo = rlo.min(bins[i].0);
        rhi = rhi.max(bins[i].1);
        rn += bins[i].2;
        right_cost[i - 1] = if rn > 0 {
            area(rlo, rhi) * rn as f64
        } else {
            f64::INFINITY
        };
    }
    let (mut llo, mut lhi, mut ln) = empty;
    let mut best: Option<(f64, usize)> = None;
    for i in 0..BINS - 1 {
        llo = llo.min(bins[i].0);
        lhi = lhi.max(bins[i].1);
        ln += bins[i].2;
        if ln == 0 || ln == items.len() {
            continue;
        }
        let cost = area(llo, lhi) * ln as f64 + right_cost[i];
        if best.is_none_or(|(c, _)| cost < c) {
            best = Some((cost, i));
        }
    }
    let (_, split) = best?;
    // Partition in place: bins ≤ split first.
    let mut first = 0;
    for i in 0..items.len() {
        if bin(items[i].centroid[axis]) <= split {
            items.swap(first, i);
            first += 1;
        }
    }
    (first > 0 && first < items.len()).then_some(first)
}
