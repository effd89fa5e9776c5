//! Track–detection association (LIMOT "Multi-object Tracking", eq. 1):
//! matching scores `psi = 1 - d/alpha` for centre distances `d < d_thres`
//! (0 otherwise) or, as an option, AB3DMOT's 3D GIoU of the predicted and
//! the detected box ([`AssociationMetric`]); assignment by min-cost flow with
//! successive shortest paths (Ahuja et al. 1993), maximising the total score.
//!
//! Matrices here are tracks × detections (the paper writes detections ×
//! tracks; only the orientation differs). A zero score means "may not be
//! paired", so a pair exists only for a positive score.
//!
//! The flow network: source → track (capacity 1, cost 0), track → detection
//! (capacity 1, cost −psi) for every positive psi, track → sink (capacity 1,
//! cost 0: the track stays unassigned this frame) and detection → sink
//! (capacity 1, cost 0). One unit of flow per track is pushed; each unit takes
//! the current shortest path in the residual graph. Shortest paths use Dijkstra
//! on reduced costs with Johnson potentials, initialised in topological order
//! (the initial network is a DAG with negative costs), so each augmentation is
//! O(E log V). Detections left without flow start new tracks.

use super::box_overlap::giou_3d;
use crate::geometry::OrientedBox;
use crate::input::ObjectClass;
use nalgebra::DMatrix;
use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;

/// What a track–detection pair is scored on.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum AssociationMetric {
    /// The paper's eq. 1 on the centre distance `d` of the predicted and
    /// the detected box: `psi = 1 − d/alpha` for `d < d_thres`.
    #[default]
    CentreDistance,
    /// AB3DMOT's affinity: the 3D GIoU of the predicted box (track size)
    /// and the detected box, `psi = GIoU − min_giou` for `GIoU > min_giou`.
    /// With `distance_gate`, pairs with `d ≥ d_thres` score 0 as well.
    Giou3d {
        /// GIoU at or below which a pair may not be paired, in [-1, 1).
        min_giou: f64,
        /// Also require the centre distance to be below `d_thres`.
        distance_gate: bool,
    },
}

/// Score of one track–detection pair (paper eq. 1).
pub fn matching_score(distance_m: f64, alpha_m: f64, d_thres_m: f64) -> f64 {
    if distance_m < d_thres_m {
        1.0 - distance_m / alpha_m
    } else {
        0.0
    }
}

impl AssociationMetric {
    /// Score of the track's `predicted` box against the `detected` box
    /// (positive: may be paired; 0: may not).
    pub fn score(
        &self,
        predicted: &OrientedBox,
        detected: &OrientedBox,
        alpha_m: f64,
        d_thres_m: f64,
    ) -> f64 {
        let distance_m = (predicted.center - detected.center).norm();
        match *self {
            AssociationMetric::CentreDistance => matching_score(distance_m, alpha_m, d_thres_m),
            AssociationMetric::Giou3d {
                min_giou,
                distance_gate,
            } => {
                // Outside the gate (or not finite): eq. 1 scores it 0.
                if distance_gate && matching_score(distance_m, alpha_m, d_thres_m) <= 0.0 {
                    return 0.0;
                }
                let giou = giou_3d(predicted, detected);
                if giou > min_giou {
                    giou - min_giou
                } else {
                    0.0
                }
            }
        }
    }
}

/// Scores between tracks and detections: `score(i, j)` scores track `i`
/// (predicted at the time detection `j` was seen) against detection `j`,
/// asked for same-class pairs only; pairs of different classes score 0.
pub fn matching_matrix(
    track_classes: &[ObjectClass],
    detection_classes: &[ObjectClass],
    score: impl Fn(usize, usize) -> f64,
) -> DMatrix<f64> {
    DMatrix::from_fn(track_classes.len(), detection_classes.len(), |i, j| {
        if track_classes[i] != detection_classes[j] {
            return 0.0;
        }
        score(i, j)
    })
}

/// Associates per class: only pairs with the same class and a positive score
/// are considered; each class is solved as its own (smaller) flow problem.
/// Returns (track index, detection index) pairs sorted by track index.
pub fn associate_by_class(
    psi: &DMatrix<f64>,
    track_classes: &[ObjectClass],
    detection_classes: &[ObjectClass],
) -> Vec<(usize, usize)> {
    assert_eq!(psi.nrows(), track_classes.len(), "one class per track row");
    assert_eq!(
        psi.ncols(),
        detection_classes.len(),
        "one class per detection column"
    );
    let mut pairs = Vec::new();
    for class in ObjectClass::ALL {
        let rows: Vec<usize> = (0..track_classes.len())
            .filter(|&i| track_classes[i] == class)
            .collect();
        let cols: Vec<usize> = (0..detection_classes.len())
            .filter(|&j| detection_classes[j] == class)
            .collect();
        if rows.is_empty() || cols.is_empty() {
            continue;
        }
        let sub = DMatrix::from_fn(rows.len(), cols.len(), |r, c| psi[(rows[r], cols[c])]);
        pairs.extend(
            max_score_assignment(&sub)
                .into_iter()
                .map(|(r, c)| (rows[r], cols[c])),
        );
    }
    pairs.sort_unstable();
    pairs
}

/// Partial assignment maximising the sum of `psi` over the chosen pairs
/// (only positive, finite entries may be chosen). Returns (row, column) pairs
/// sorted by row.
pub fn max_score_assignment(psi: &DMatrix<f64>) -> Vec<(usize, usize)> {
    // Connected components of the "may pair" graph are independent problems;
    // with gated scores they are small (usually one track and one detection),
    // so solving them apart is much cheaper than one large flow.
    let (n_tracks, n_dets) = psi.shape();
    let allowed = |i: usize, j: usize| psi[(i, j)] > 0.0 && psi[(i, j)].is_finite();
    // Union-find over tracks 0..n_tracks and detections n_tracks.. .
    let mut parent: Vec<usize> = (0..n_tracks + n_dets).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for i in 0..n_tracks {
        for j in 0..n_dets {
            if allowed(i, j) {
                let (a, b) = (find(&mut parent, i), find(&mut parent, n_tracks + j));
                parent[a] = b;
            }
        }
    }
    let mut components: Vec<(Vec<usize>, Vec<usize>)> = Vec::new();
    let mut index_of_root = vec![usize::MAX; n_tracks + n_dets];
    for node in 0..n_tracks + n_dets {
        let root = find(&mut parent, node);
        if index_of_root[root] == usize::MAX {
            index_of_root[root] = components.len();
            components.push((Vec::new(), Vec::new()));
        }
        let component = &mut components[index_of_root[root]];
        if node < n_tracks {
            component.0.push(node);
        } else {
            component.1.push(node - n_tracks);
        }
    }
    let mut pairs = Vec::new();
    for (rows, cols) in components {
        match (rows.len(), cols.len()) {
            (0, _) | (_, 0) => {}
            // A single allowed pair: take it.
            (1, 1) => pairs.push((rows[0], cols[0])),
            _ => {
                let sub = DMatrix::from_fn(rows.len(), cols.len(), |r, c| psi[(rows[r], cols[c])]);
                pairs.extend(
                    solve_flow(&sub)
                        .into_iter()
                        .map(|(r, c)| (rows[r], cols[c])),
                );
            }
        }
    }
    pairs.sort_unstable();
    pairs
}

/// Min-cost flow on one (connected) problem; see the module comment.
fn solve_flow(psi: &DMatrix<f64>) -> Vec<(usize, usize)> {
    let (n_tracks, n_dets) = psi.shape();
    if n_tracks == 0 || n_dets == 0 {
        return Vec::new();
    }
    // Node numbering: source, tracks, detections, sink.
    let source = 0;
    let track_node = |i: usize| 1 + i;
    let det_node = |j: usize| 1 + n_tracks + j;
    let sink = 1 + n_tracks + n_dets;
    let mut net = FlowNetwork::new(sink + 1);
    for i in 0..n_tracks {
        net.add_edge(source, track_node(i), 0.0);
        net.add_edge(track_node(i), sink, 0.0);
    }
    let mut pair_edges = Vec::new();
    for i in 0..n_tracks {
        for j in 0..n_dets {
            let score = psi[(i, j)];
            if score > 0.0 && score.is_finite() {
                let e = net.add_edge(track_node(i), det_node(j), -score);
                pair_edges.push((e, i, j));
            }
        }
    }
    for j in 0..n_dets {
        net.add_edge(det_node(j), sink, 0.0);
    }

    // Initial potentials = shortest distances from the source in the DAG
    // source → tracks → detections → sink (all costs ≤ 0 only on pair edges).
    let mut potential = vec![0.0; net.n_nodes()];
    for &(e, i, j) in &pair_edges {
        let d = potential[track_node(i)] + net.edges[e].cost;
        if d < potential[det_node(j)] {
            potential[det_node(j)] = d;
        }
    }
    potential[sink] = (0..n_dets)
        .map(|j| potential[det_node(j)])
        .fold(0.0, f64::min);

    for _ in 0..n_tracks {
        if !net.augment_shortest_path(source, sink, &mut potential) {
            break;
        }
    }
    let mut pairs: Vec<(usize, usize)> = pair_edges
        .into_iter()
        .filter(|&(e, _, _)| net.edges[e].capacity == 0)
        .map(|(_, i, j)| (i, j))
        .collect();
    pairs.sort_unstable();
    pairs
}

#[derive(Debug, Clone)]
struct Edge {
    to: usize,
    /// Residual capacity (all original capacities are 1).
    capacity: u32,
    cost: f64,
}

/// Residual network with paired forward/backward edges (`e ^ 1` is the twin).
struct FlowNetwork {
    edges: Vec<Edge>,
    out: Vec<Vec<usize>>,
}

impl FlowNetwork {
    fn new(n_nodes: usize) -> Self {
        FlowNetwork {
            edges: Vec::new(),
            out: vec![Vec::new(); n_nodes],
        }
    }

    fn n_nodes(&self) -> usize {
        self.out.len()
    }

    /// Adds a unit-capacity edge and its residual twin; returns the forward id.
    fn add_edge(&mut self, from: usize, to: usize, cost: f64) -> usize {
        let id = self.edges.len();
        self.edges.push(Edge {
            to,
            capacity: 1,
            cost,
        });
        self.edges.push(Edge {
            to: from,
            capacity: 0,
            cost: -cost,
        });
        self.out[from].push(id);
        self.out[to].push(id + 1);
        id
    }

    /// One unit along the cheapest residual path (Dijkstra with a binary
    /// heap on reduced costs); updates the potentials. Returns false when the
    /// sink is unreachable.
    fn augment_shortest_path(&mut self, source: usize, sink: usize, potential: &mut [f64]) -> bool {
        let n = self.n_nodes();
        let mut dist = vec![f64::INFINITY; n];
        let mut via_edge = vec![usize::MAX; n];
        let mut done = vec![false; n];
        let mut heap = BinaryHeap::new();
        dist[source] = 0.0;
        heap.push(Reverse(HeapEntry(0.0, source)));
        while let Some(Reverse(HeapEntry(d_u, u))) = heap.pop() {
            if done[u] {
                continue;
            }
            done[u] = true;
            for &e in &self.out[u] {
                let edge = &self.edges[e];
                if edge.capacity == 0 || done[edge.to] {
                    continue;
                }
                // Reduced costs are ≥ 0 up to round-off; clamp the round-off.
                let reduced = (edge.cost + potential[u] - potential[edge.to]).max(0.0);
                let d = d_u + reduced;
                if d < dist[edge.to] {
                    dist[edge.to] = d;
                    via_edge[edge.to] = e;
                    heap.push(Reverse(HeapEntry(d, edge.to)));
                }
            }
        }
        if !dist[sink].is_finite() {
            return false;
        }
        // Nodes unreachable now stay unreachable (new residual edges only join
        // reachable nodes), so their potentials never matter again.
        for v in 0..n {
            if dist[v].is_finite() {
                potential[v] += dist[v];
            }
        }
        let mut v = sink;
        while v != source {
            let e = via_edge[v];
            self.edges[e].capacity -= 1;
            self.edges[e ^ 1].capacity += 1;
            v = self.edges[e ^ 1].to;
        }
        true
    }
}

/// Heap entry ordered by distance (finite, non-negative), then node.
#[derive(Debug, Clone, Copy, PartialEq)]
struct HeapEntry(f64, usize);

impl Eq for HeapEntry {}

impl PartialOrd for HeapEntry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for HeapEntry {
    fn cmp(&self, other: &Self) -> Ordering {
        self.0.total_cmp(&other.0).then(self.1.cmp(&other.1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use std::f64::consts::PI;

    #[test]
    fn score_follows_eq_1() {
        assert!((matching_score(1.0, 100.0, 2.0) - 0.99).abs() < 1e-15);
        assert_eq!(matching_score(2.0, 100.0, 2.0), 0.0);
        assert_eq!(matching_score(f64::NAN, 100.0, 2.0), 0.0);
    }

    #[test]
    fn greedy_is_not_optimal_but_flow_is() {
        // Greedy would take (0,0)=0.9 and leave track 1 unmatched (0.9);
        // the optimum pairs (0,1)+(1,0) = 0.8 + 0.85.
        let psi = DMatrix::from_row_slice(2, 2, &[0.9, 0.8, 0.85, 0.0]);
        assert_eq!(max_score_assignment(&psi), vec![(0, 1), (1, 0)]);
    }

    #[test]
    fn zero_scores_are_never_paired() {
        let psi = DMatrix::from_row_slice(2, 3, &[0.0, 0.0, 0.0, 0.0, 0.5, 0.0]);
        assert_eq!(max_score_assignment(&psi), vec![(1, 1)]);
        assert!(max_score_assignment(&DMatrix::zeros(0, 4)).is_empty());
    }

    #[test]
    fn classes_do_not_mix() {
        let psi = DMatrix::from_element(2, 2, 0.9);
        let tracks = [ObjectClass::Car, ObjectClass::Pedestrian];
        let dets = [ObjectClass::Pedestrian, ObjectClass::Truck];
        assert_eq!(associate_by_class(&psi, &tracks, &dets), vec![(1, 0)]);
    }

    #[test]
    fn matching_matrix_uses_distance_and_class() {
        let tracks = [(Vector3::new(0.0, 0.0, 0.0), ObjectClass::Car)];
        let dets = [
            (Vector3::new(1.0, 0.0, 0.0), ObjectClass::Car),
            (Vector3::new(0.5, 0.0, 0.0), ObjectClass::Cyclist),
            (Vector3::new(3.0, 0.0, 0.0), ObjectClass::Car),
        ];
        let psi = matching_matrix(&tracks.map(|t| t.1), &dets.map(|d| d.1), |i, j| {
            matching_score((tracks[i].0 - dets[j].0).norm(), 100.0, 2.0)
        });
        assert!((psi[(0, 0)] - 0.99).abs() < 1e-15);
        assert_eq!(psi[(0, 1)], 0.0);
        assert_eq!(psi[(0, 2)], 0.0);
    }

    fn car(x: f64, y: f64, yaw: f64) -> OrientedBox {
        OrientedBox {
            center: Vector3::new(x, y, 0.8),
            yaw_rad: yaw,
            size_lwh: Vector3::new(4.0, 2.0, 1.5),
        }
    }

    #[test]
    fn giou_metric_scores_overlap_above_its_floor() {
        let metric = AssociationMetric::Giou3d {
            min_giou: -0.2,
            distance_gate: false,
        };
        let track = car(0.0, 0.0, 0.0);
        // 1 m along the length: GIoU 0.6, so psi 0.8.
        assert!((metric.score(&track, &car(1.0, 0.0, 0.0), 100.0, 2.0) - 0.8).abs() < 1e-12);
        // 2.5 m sideways, boxes apart by 0.5 m: GIoU = −(C − U)/C with
        // C = 4·4.5·1.5 = 27, U = 24: −1/9 > −0.2, still a candidate,
        // although beyond the 2 m centre gate.
        let side = metric.score(&track, &car(0.0, 2.5, 0.0), 100.0, 2.0);
        assert!((side - (0.2 - 1.0 / 9.0)).abs() < 1e-12, "{side}");
        assert_eq!(
            AssociationMetric::CentreDistance.score(&track, &car(0.0, 2.5, 0.0), 100.0, 2.0),
            0.0
        );
        // The optional centre gate removes it.
        let gated = AssociationMetric::Giou3d {
            min_giou: -0.2,
            distance_gate: true,
        };
        assert_eq!(gated.score(&track, &car(0.0, 2.5, 0.0), 100.0, 2.0), 0.0);
        // Far away: GIoU below the floor, never paired.
        assert_eq!(metric.score(&track, &car(8.0, 0.0, 0.0), 100.0, 2.0), 0.0);
        // A box crossing the track at right angles overlaps less than one
        // shifted along it by the same distance.
        let along = metric.score(&track, &car(1.0, 0.0, 0.0), 100.0, 2.0);
        let across = metric.score(&track, &car(1.0, 0.0, PI / 2.0), 100.0, 2.0);
        assert!(across < along, "{across} vs {along}");
    }
}
