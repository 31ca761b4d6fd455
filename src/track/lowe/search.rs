//! Best-first search for a consistent set of matches (001 "Best-first
//! search"), then "locking on" (Figs. 3–6).
//!
//! 1. **A node** takes, from the candidates ranked by their current
//!    probability of correctness, the best ones with distinct model and
//!    image segments until there are enough to constrain the n parameters
//!    with redundancy (⌊n/2⌋ + 1 segments, two measurements each: 4 for the
//!    7-parameter hinged box, as in 001), then more while the product of
//!    their probabilities stays above `set_probability` (0.9).
//! 2. The set is solved by stabilised Gauss–Newton from the prediction and
//!    accepted when its residual σ is at most `residual_ratio` times the
//!    measurement σ.
//! 3. **On rejection** at least one member is wrong: each member's
//!    probability is multiplied by 1 − 1/n for a set of n (the paper's
//!    "reduced by 1/n", read as a relative reduction so probabilities stay
//!    in [0, 1]), the set is remembered, and the next node is formed from
//!    the updated ranking, never containing a complete rejected set. At
//!    most `max_branches` nodes are tried per frame (001: 5).
//! 4. **Locking on**: after acceptance the model is re-predicted with the
//!    solution's reduced covariance, every candidate is re-scored (eq. 2–3)
//!    and each image segment whose best probability is at least
//!    `lock_probability` joins (one model segment may take several
//!    collinear pieces); the enlarged set is solved from the solution and
//!    kept when its residual passes. When it does not, some newcomer is
//!    wrong: the solution is kept and the next re-prediction admits only
//!    matches more probable than before (the threshold moves half way to
//!    1). This repeats until the set stops changing, at most
//!    `lock_iterations` times.
//!    With `remember_contrast` (our addition, on by default), an edge of
//!    the model keeps one contrast along its length (it separates the same
//!    two surfaces), and the side of it its matches were dark on over the
//!    last verified frames is remembered, while the same faces of it face
//!    the camera ([`SearchFrame::remembered_contrast`]). Of two image
//!    segments side by side on one model segment with opposite contrast,
//!    the one of the contrast the edge has not shown does not join (and
//!    the frame's verification counts along the edge only the zero
//!    crossings of the remembered contrast: the tracker's module doc,
//!    step 7). A lid
//!    edge holding pieces of its own line and of a parallel line 2 px
//!    beside it of the other contrast (the hinged box half hidden, frame
//!    93) is fitted between the two, and the lid turns 3° off. Replayed
//!    over the matches of that run, wherever an edge held pieces of both
//!    contrasts and the true pose told which was its own, the remembered
//!    contrast was the right one in all 96 such cases (an edge on a frame)
//!    where one was known, and in 107 of 109 at 20 px/frame. What it
//!    gains over the stress runs: `LoweParams::remember_contrast`.
//! 5. **Verification**: the branch ends the search only when its locked-on
//!    solution is verified (overdetermined enough: see
//!    [`SearchFrame::verify`]); otherwise the node counts as rejected (step
//!    3) and the search goes on — "this branch continues to be explored and
//!    new matches are attempted until no more can be found", then judged.
//! 6. **Neighbouring parallel edges** (our addition): the two long edges of
//!    a thin face seen at a grazing angle (the 1 cm front of a lid) lie a
//!    few pixels apart, and often only one of them shows as an image
//!    segment; matching it to the wrong one of the pair fits as well and
//!    shifts the model by the face's width, and the next frames keep the
//!    shift. So after a verified solution, every matched model segment
//!    with an unmatched, nearly parallel neighbour beside it within
//!    `swap_gap` px is tried the other way round: its image segments are
//!    given to the neighbour, the set is solved and locked on, and the swap
//!    is kept when the new solution is verified and its matches cover more
//!    of its visible model ([`SearchFrame::covered_length`]) by at least a
//!    quarter of the neighbour's length: at the right state the edges
//!    around the thin face (the lid's sides, whose image segments the
//!    overlap test of eq. 3 refuses at the wrong one) find their matches.
//!    It is kept as well when it covers no less with as many matches or
//!    more and its residual σ is at most `swap_residual_ratio` of the
//!    solution's: the sides may have found their matches either way (the
//!    lid's 1 cm front 2–3 px wide), and only the closer fit tells.
//!    When both lines of the pair were found and both joined the one model
//!    segment (the fit then lies between them, 2 px off each), the swap
//!    that gives the neighbour only the image segments on its side is
//!    tried as well. At most [`MAX_SWAPS`] swaps are kept per frame.

use super::estimation::{Match, Matrix, Problem, Solution, solve};
use super::matching::{Candidate, Endpoints};
use super::projection::{ModelSegment, State};

/// What the search needs from the frame: the visible model segments at a
/// state, the candidates of those segments under a covariance, and the
/// image segments' endpoints.
pub trait SearchFrame {
    /// The visible model segments at `state` (replacing `out`'s contents).
    fn model_segments(&self, state: &State, out: &mut Vec<ModelSegment>);
    /// The candidates of `segs` under covariance `p` (replacing `out`'s contents).
    fn candidates(&self, segs: &[ModelSegment], p: &Matrix, out: &mut Vec<Candidate>);
    /// Endpoints of image segment `image`.
    fn endpoints(&self, image: usize) -> Endpoints;
    /// Direction across image segment `image` from its bright side to its
    /// dark side, radians; `None` when the frame does not know it.
    fn contrast_direction(&self, image: usize) -> Option<f64>;
    /// The side of `seg` its edge has shown dark on the last verified
    /// frames with the same faces facing the camera: +1 along the
    /// segment's normal, −1 against it, 0 when not known (module doc,
    /// step 4).
    fn remembered_contrast(&self, seg: &ModelSegment) -> f64;
    /// The outline support of a locked-on solution with these matches, the
    /// model segments at its state and its residual σ (px) when it is
    /// verified (overdetermined enough to end the search), `None` when it
    /// is not.
    fn verify(&self, segs: &[ModelSegment], matches: &[Match], residual_sigma: Option<f64>) -> Option<Support>;
    /// Length of `segs` covered by the matched image segments, px.
    fn covered_length(&self, segs: &[ModelSegment], matches: &[Match]) -> f64;
}

/// Most parallel-edge swaps kept per frame (module doc, step 6).
pub const MAX_SWAPS: usize = 2;

/// Search settings (from `LoweParams`).
#[derive(Clone, Copy, Debug)]
pub struct SearchSettings {
    /// Product of probabilities a node's set stays above.
    pub set_probability: f64,
    /// Residual limit, px.
    pub residual_limit: f64,
    /// Nodes per frame.
    pub max_branches: usize,
    /// Gauss–Newton iterations per solution.
    pub iterations: usize,
    /// Re-predictions after acceptance.
    pub lock_iterations: usize,
    /// Least probability of a match joining after acceptance.
    pub lock_probability: f64,
    /// Widest gap between parallel neighbours tried the other way round,
    /// px (module doc, step 6); 0 tries none.
    pub swap_gap: f64,
    /// A swap that covers as much with as many matches is kept when its
    /// residual σ is at most this share of the solution's (module doc,
    /// step 6); 0 keeps none that way.
    pub swap_residual_ratio: f64,
}

/// The result of one frame's search.
#[derive(Clone, Debug, Default)]
pub struct SearchOutcome {
    /// The accepted solution after locking on, if a node was accepted.
    pub solution: Option<Solution>,
    /// Its matches.
    pub matches: Vec<Match>,
    /// Nodes tried (accepted one included).
    pub branches: usize,
    /// Re-predictions done while locking on.
    pub lock_steps: usize,
    /// Model segments (at the final state, or the prediction without a solution).
    pub model_segments: Vec<ModelSegment>,
    /// The solution's outline support when it passed
    /// [`SearchFrame::verify`], `None` for an unverified solution (the
    /// branch that locked on to the most matches).
    pub support: Option<Support>,
}

/// `(supported, samples)` of a verified solution's outline, as the frame
/// counts it ([`SearchFrame::verify`]).
pub type Support = (usize, usize);

/// Segments needed for a node with n parameters: ⌊n/2⌋ + 1.
#[must_use]
pub fn segments_needed(n: usize) -> usize {
    n / 2 + 1
}

/// Whether `set` (sorted) contains every member of some rejected set.
fn contains_rejected(set: &[usize], rejected: &[Vec<usize>]) -> bool {
    rejected.iter().any(|r| r.iter().all(|c| set.binary_search(c).is_ok()))
}

/// The next node's set (sorted candidate indices), `None` when no set of
/// `needed` members can be formed.
fn node_set(
    candidates: &[Candidate],
    probabilities: &[f64],
    rejected: &[Vec<usize>],
    needed: usize,
    set_probability: f64,
) -> Option<Vec<usize>> {
    let mut order: Vec<usize> = (0..candidates.len()).filter(|&c| probabilities[c] > 0.0).collect();
    order.sort_by(|&a, &b| probabilities[b].total_cmp(&probabilities[a]).then(a.cmp(&b)));
    let mut set: Vec<usize> = Vec::new();
    let mut product = 1.0;
    for c in order {
        let cand = candidates[c];
        if set.iter().any(|&s| candidates[s].model == cand.model || candidates[s].image == cand.image) {
            continue;
        }
        if set.len() >= needed && product * probabilities[c] < set_probability {
            break;
        }
        let at = set.binary_search(&c).unwrap_or_else(|e| e);
        set.insert(at, c);
        if contains_rejected(&set, rejected) {
            set.remove(at);
            continue;
        }
        product *= probabilities[c];
    }
    (set.len() >= needed).then_some(set)
}

fn to_matches(frame: &dyn SearchFrame, segs: &[ModelSegment], candidates: &[Candidate], set: &[usize]) -> Vec<Match> {
    set.iter()
        .map(|&c| {
            let cand = candidates[c];
            let seg = &segs[cand.model];
            Match { edge: seg.edge, interval: seg.interval, endpoints: frame.endpoints(cand.image), image: cand.image }
        })
        .collect()
}

fn passes(solution: &Solution, limit: f64) -> bool {
    solution.residual_sigma.is_none_or(|s| s <= limit)
}

/// Run the search of the module doc for one frame: `problem` holds the
/// prediction and its prior, `segs` and `candidates` were computed at the
/// prediction under the prior covariance.
#[must_use]
pub fn search(
    frame: &dyn SearchFrame,
    problem: &Problem<'_>,
    segs: Vec<ModelSegment>,
    candidates: &[Candidate],
    settings: &SearchSettings,
) -> SearchOutcome {
    let n = 6 + problem.geometry.joint_count();
    let needed = segments_needed(n);
    let mut probabilities: Vec<f64> = candidates.iter().map(|c| c.probability).collect();
    let mut rejected: Vec<Vec<usize>> = Vec::new();
    let mut outcome = SearchOutcome { model_segments: segs, ..SearchOutcome::default() };
    let mut best_unverified: Option<(Solution, Vec<Match>, Vec<ModelSegment>)> = None;
    while outcome.branches < settings.max_branches {
        let Some(set) = node_set(candidates, &probabilities, &rejected, needed, settings.set_probability) else {
            break;
        };
        outcome.branches += 1;
        let matches = to_matches(frame, &outcome.model_segments, candidates, &set);
        if let Some(solution) = solve(problem, problem.prediction, &matches, settings.iterations)
            && passes(&solution, settings.residual_limit)
        {
            let (solution, matches, final_segs, steps) = lock_on(frame, problem, solution, matches, settings, needed);
            outcome.lock_steps += steps;
            if let Some(support) = frame.verify(&final_segs, &matches, solution.residual_sigma) {
                let verified = Verified { solution, matches, segs: final_segs, support };
                let Verified { solution, matches, segs, support } =
                    swap_parallel(frame, problem, verified, settings, needed);
                outcome.solution = Some(solution);
                outcome.matches = matches;
                outcome.model_segments = segs;
                outcome.support = Some(support);
                return outcome;
            }
            if best_unverified.as_ref().is_none_or(|(_, m, _)| m.len() < matches.len()) {
                best_unverified = Some((solution, matches, final_segs));
            }
        }
        let keep = 1.0 - 1.0 / set.len() as f64;
        for &c in &set {
            probabilities[c] *= keep;
        }
        rejected.push(set);
    }
    if let Some((solution, matches, final_segs)) = best_unverified {
        outcome.solution = Some(solution);
        outcome.matches = matches;
        outcome.model_segments = final_segs;
    }
    outcome
}

/// Locking on from an accepted node (module doc, step 4): the final
/// solution, its matches, the model segments at its state and the number of
/// re-predictions.
fn lock_on(
    frame: &dyn SearchFrame,
    problem: &Problem<'_>,
    mut solution: Solution,
    mut matches: Vec<Match>,
    settings: &SearchSettings,
    needed: usize,
) -> (Solution, Vec<Match>, Vec<ModelSegment>, usize) {
    let mut segs_now = Vec::new();
    let mut cands_now = Vec::new();
    let mut threshold = settings.lock_probability;
    let mut steps = 0;
    for _ in 0..settings.lock_iterations {
        frame.model_segments(&solution.state, &mut segs_now);
        frame.candidates(&segs_now, &solution.covariance, &mut cands_now);
        let locked = lock_set(frame, &segs_now, &cands_now, threshold);
        if same_matches(&locked, &matches) || locked.len() < needed {
            break;
        }
        steps += 1;
        match solve(problem, &solution.state, &locked, settings.iterations) {
            Some(next) if passes(&next, settings.residual_limit) => {
                solution = next;
                matches = locked;
            }
            _ => threshold = 0.5 * (1.0 + threshold),
        }
    }
    frame.model_segments(&solution.state, &mut segs_now);
    (solution, matches, segs_now, steps)
}

/// A verified solution: its matches, the model segments at its state and
/// its outline support.
struct Verified {
    solution: Solution,
    matches: Vec<Match>,
    segs: Vec<ModelSegment>,
    support: Support,
}

/// Step 6 of the module doc: the verified solution after the kept swaps.
fn swap_parallel(
    frame: &dyn SearchFrame,
    problem: &Problem<'_>,
    mut verified: Verified,
    settings: &SearchSettings,
    needed: usize,
) -> Verified {
    if settings.swap_gap <= 0.0 {
        return verified;
    }
    let mut tried: Vec<[usize; 2]> = Vec::new();
    let mut kept = 0;
    'swaps: while kept < MAX_SWAPS {
        let Verified { solution, matches, segs, .. } = &verified;
        let before = frame.covered_length(segs, matches);
        for [from, to] in parallel_neighbours(segs, matches, settings.swap_gap) {
            let (f, t) = (&segs[from], &segs[to]);
            if tried.contains(&[f.edge, t.edge]) {
                continue;
            }
            tried.push([f.edge, t.edge]);
            let gain = 0.25 * t.length();
            for moved in swap_choices(f, t, matches) {
                let swapped: Vec<Match> = matches
                    .iter()
                    .zip(&moved)
                    .map(|(m, &go)| if go { Match { edge: t.edge, interval: t.interval, ..*m } } else { *m })
                    .collect();
                let Some(first) = solve(problem, &solution.state, &swapped, settings.iterations) else { continue };
                if !passes(&first, settings.residual_limit) {
                    continue;
                }
                let (next, next_matches, next_segs, _) = lock_on(frame, problem, first, swapped, settings, needed);
                let Some(support) = frame.verify(&next_segs, &next_matches, next.residual_sigma) else { continue };
                let covered = frame.covered_length(&next_segs, &next_matches);
                // As much covered by as many matches, and a clearly closer fit.
                let closer = settings.swap_residual_ratio > 0.0
                    && covered >= before
                    && next_matches.len() >= matches.len()
                    && matches!(
                        (next.residual_sigma, solution.residual_sigma),
                        (Some(after), Some(now)) if after <= settings.swap_residual_ratio * now
                    );
                if covered >= before + gain || closer {
                    verified = Verified { solution: next, matches: next_matches, segs: next_segs, support };
                    kept += 1;
                    continue 'swaps;
                }
            }
        }
        break;
    }
    verified
}

/// Which of `matches` a swap from model segment `from` to its unmatched
/// parallel neighbour `to` gives to `to` (module doc, step 6), as flags
/// over `matches`: first all of `from`'s image segments; then, when they
/// lie on both sides of `from`'s line (both lines of the pair were found
/// and both joined `from`, the fit splitting the difference), only those on
/// `to`'s side.
fn swap_choices(from: &ModelSegment, to: &ModelSegment, matches: &[Match]) -> Vec<Vec<bool>> {
    let of_from = |m: &Match| m.edge == from.edge && m.interval == from.interval;
    let [nx, ny] = from.normal();
    let across = |p: [f64; 2]| (p[0] - from.a[0]) * nx + (p[1] - from.a[1]) * ny;
    let side = across([0.5 * (to.a[0] + to.b[0]), 0.5 * (to.a[1] + to.b[1])]).signum();
    let offset = |m: &Match| {
        let [p, q] = m.endpoints;
        side * across([0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])])
    };
    let all: Vec<bool> = matches.iter().map(of_from).collect();
    let toward: Vec<bool> = matches.iter().map(|m| of_from(m) && offset(m) > COINCIDENT_PX).collect();
    let away = matches.iter().any(|m| of_from(m) && offset(m) < -COINCIDENT_PX);
    let mut choices = vec![all];
    if away && toward.contains(&true) {
        choices.push(toward);
    }
    choices
}

/// Pairs `[matched, unmatched]` of model segments of different edges,
/// nearly parallel (within 10°), beside each other over at least half the
/// shorter one's length, the shorter one's ends more than
/// [`COINCIDENT_PX`] and less than `max_gap` px from the other's line;
/// nearest first.
fn parallel_neighbours(segs: &[ModelSegment], matches: &[Match], max_gap: f64) -> Vec<[usize; 2]> {
    let max_sine = 10f64.to_radians().sin();
    let matched: Vec<bool> =
        segs.iter().map(|s| matches.iter().any(|m| m.edge == s.edge && m.interval == s.interval)).collect();
    let mut pairs = Vec::new();
    for (i, a) in segs.iter().enumerate().filter(|&(i, _)| matched[i]) {
        for (j, b) in segs.iter().enumerate().filter(|&(j, _)| !matched[j]) {
            if a.edge == b.edge {
                continue;
            }
            let (long, short) = if a.length() >= b.length() { (a, b) } else { (b, a) };
            let [ux, uy] = long.direction();
            let [vx, vy] = short.direction();
            if (ux * vy - uy * vx).abs() > max_sine {
                continue;
            }
            let along = |p: [f64; 2]| (p[0] - long.a[0]) * ux + (p[1] - long.a[1]) * uy;
            let across = |p: [f64; 2]| ((p[1] - long.a[1]) * ux - (p[0] - long.a[0]) * uy).abs();
            let (ta, tb) = (along(short.a), along(short.b));
            let overlap = ta.max(tb).min(long.length()) - ta.min(tb).max(0.0);
            let (ga, gb) = (across(short.a), across(short.b));
            if overlap >= 0.5 * short.length() && ga.min(gb) > COINCIDENT_PX && ga.max(gb) < max_gap {
                pairs.push((ga + gb, [i, j]));
            }
        }
    }
    pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
    pairs.into_iter().map(|(_, pair)| pair).collect()
}

/// Model segments nearer than this to each other are one edge seen twice
/// (a hinge, a lid resting on its box), px.
pub const COINCIDENT_PX: f64 = 0.5;

/// Each image segment joins its most probable model segment when that
/// probability is at least `min_probability`.
fn lock_set(frame: &dyn SearchFrame, segs: &[ModelSegment], cands: &[Candidate], min_probability: f64) -> Vec<Match> {
    let mut best: Vec<(usize, Candidate)> = Vec::new();
    for c in cands.iter().filter(|c| c.probability >= min_probability) {
        match best.iter_mut().find(|(image, _)| *image == c.image) {
            Some((_, held)) if held.probability < c.probability => *held = *c,
            Some(_) => {}
            None => best.push((c.image, *c)),
        }
    }
    let left_out = contrast_conflicts(frame, segs, &best);
    best.retain(|(image, _)| !left_out.contains(image));
    best.sort_by_key(|(image, _)| *image);
    best.iter()
        .map(|(image, c)| {
            let seg = &segs[c.model];
            Match { edge: seg.edge, interval: seg.interval, endpoints: frame.endpoints(*image), image: *image }
        })
        .collect()
}

/// Farthest apart across a model segment two image segments on it may lie
/// (their midpoints) to be side by side (module doc, step 4), px.
pub const SIDE_BY_SIDE_PX: f64 = 8.0;

/// Image segments of `assigned` (each with the candidate it joins) to leave
/// out of a lock-on set (module doc, step 4): of two on one model segment
/// that lie side by side — overlapping along it over at least half the
/// shorter one's length, at most [`SIDE_BY_SIDE_PX`] apart across it — with
/// opposite contrast across it, the one whose contrast is not the one its
/// edge has shown ([`SearchFrame::remembered_contrast`]).
fn contrast_conflicts(frame: &dyn SearchFrame, segs: &[ModelSegment], assigned: &[(usize, Candidate)]) -> Vec<usize> {
    let mut conflicts = Vec::new();
    for (i, &(image_a, a)) in assigned.iter().enumerate() {
        for &(image_b, b) in &assigned[i + 1..] {
            if a.model != b.model {
                continue;
            }
            let seg = &segs[a.model];
            let remembered = frame.remembered_contrast(seg);
            if remembered == 0.0 {
                continue;
            }
            let (side_a, side_b) = (contrast_side(frame, image_a, seg), contrast_side(frame, image_b, seg));
            if side_a * side_b >= 0.0 {
                continue;
            }
            let [ux, uy] = seg.direction();
            let [nx, ny] = seg.normal();
            // The image segment's extent along the model segment and its
            // midpoint's signed distance from the model segment's line.
            let place = |image: usize| {
                let [p, q] = frame.endpoints(image);
                let (s, t) = (p[0] * ux + p[1] * uy, q[0] * ux + q[1] * uy);
                let mid = [0.5 * (p[0] + q[0]) - seg.a[0], 0.5 * (p[1] + q[1]) - seg.a[1]];
                (s.min(t), s.max(t), mid[0] * nx + mid[1] * ny)
            };
            let ((a0, a1, da), (b0, b1, db)) = (place(image_a), place(image_b));
            let overlap = a1.min(b1) - a0.max(b0);
            if overlap >= 0.5 * (a1 - a0).min(b1 - b0) && (da - db).abs() <= SIDE_BY_SIDE_PX {
                conflicts.push(if side_a == remembered { image_b } else { image_a });
            }
        }
    }
    conflicts
}

/// Which side of `seg` image segment `image` is dark on ([`dark_side`]);
/// 0 when the frame does not know its contrast.
fn contrast_side(frame: &dyn SearchFrame, image: usize, seg: &ModelSegment) -> f64 {
    frame.contrast_direction(image).map_or(0.0, |d| dark_side(d, seg))
}

/// Which side of `seg` an image segment whose contrast runs in `direction`
/// (radians, bright side to dark side) is dark on: +1 along the segment's
/// normal, −1 against it, 0 when that direction lies within 60° of the
/// segment.
#[must_use]
pub fn dark_side(direction: f64, seg: &ModelSegment) -> f64 {
    let [nx, ny] = seg.normal();
    let across = direction.cos() * nx + direction.sin() * ny;
    if across.abs() < 0.5 { 0.0 } else { across.signum() }
}

fn same_matches(a: &[Match], b: &[Match]) -> bool {
    let key = |m: &Match| (m.image, m.edge);
    let mut ka: Vec<_> = a.iter().map(key).collect();
    let mut kb: Vec<_> = b.iter().map(key).collect();
    ka.sort_unstable();
    kb.sort_unstable();
    ka == kb
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::geometry::{Camera, ModelGeometry, Pose};
    use crate::track::lowe::fixtures::{camera, hinged_box, vertex_error};
    use crate::track::lowe::matching::{MatchContext, all_candidates};
    use crate::track::lowe::params::MAX_PARAMS;
    use crate::track::lowe::projection::Linearised;

    struct Brute<'a> {
        geometry: &'a ModelGeometry,
        camera: &'a Camera,
        images: Vec<Endpoints>,
        ctx: MatchContext,
        /// Extra probability given to chosen (model edge, image) pairs, to
        /// plant a decoy at the top of the ranking.
        boost: Vec<(usize, usize)>,
    }

    impl SearchFrame for Brute<'_> {
        fn model_segments(&self, state: &State, out: &mut Vec<ModelSegment>) {
            let lin = Linearised::at(self.geometry, state, self.geometry.centroid()).unwrap();
            out.clear();
            out.extend(
                (0..self.geometry.edges().len())
                    .filter_map(|e| ModelSegment::new(&lin, self.camera, self.geometry.edges(), e, [0.0, 1.0])),
            );
        }
        fn candidates(&self, segs: &[ModelSegment], p: &Matrix, out: &mut Vec<Candidate>) {
            *out = all_candidates(segs, p, 7, &self.images, &self.ctx);
            for c in out.iter_mut() {
                if self.boost.contains(&(segs[c.model].edge, c.image)) {
                    c.probability = 0.999_999;
                }
            }
        }
        fn endpoints(&self, image: usize) -> Endpoints {
            self.images[image]
        }
        fn contrast_direction(&self, _image: usize) -> Option<f64> {
            None
        }
        fn remembered_contrast(&self, _seg: &ModelSegment) -> f64 {
            0.0
        }
        fn verify(&self, _segs: &[ModelSegment], matches: &[Match], _residual_sigma: Option<f64>) -> Option<Support> {
            (matches.len() >= 8).then_some((matches.len(), matches.len()))
        }
        fn covered_length(&self, segs: &[ModelSegment], _matches: &[Match]) -> f64 {
            segs.iter().map(ModelSegment::length).sum()
        }
    }

    fn settings() -> SearchSettings {
        SearchSettings {
            set_probability: 0.9,
            residual_limit: 2.5,
            max_branches: 5,
            iterations: 3,
            lock_iterations: 4,
            lock_probability: 0.5,
            swap_gap: 0.0,
            swap_residual_ratio: 0.0,
        }
    }

    /// The true image segments of every edge at `truth` (the middle 70 %).
    fn true_images(geometry: &ModelGeometry, cam: &Camera, truth: &State) -> Vec<Endpoints> {
        let lin = Linearised::at(geometry, truth, geometry.centroid()).unwrap();
        (0..geometry.edges().len())
            .map(|e| {
                let s = ModelSegment::new(&lin, cam, geometry.edges(), e, [0.0, 1.0]).unwrap();
                let at = |t: f64| [s.a[0] + t * (s.b[0] - s.a[0]), s.a[1] + t * (s.b[1] - s.a[1])];
                [at(0.15), at(0.85)]
            })
            .collect()
    }

    fn run(boost: Vec<(usize, usize)>, decoys: &[Endpoints]) -> (SearchOutcome, f64) {
        let geometry = hinged_box();
        let cam = camera();
        let centre = geometry.centroid();
        let limits = geometry.joint_limits();
        let truth = State {
            pose: Pose::from_axis_angle(DVec3::new(0.5, -0.4, 0.1), DVec3::new(-0.12, 0.0, 0.8)),
            params: vec![0.9],
        };
        let prediction = truth.corrected(&[0.01, -0.01, 0.015, 0.004, -0.004, 0.006, -0.05], centre, &limits);
        let mut images = true_images(&geometry, &cam, &truth);
        images.extend_from_slice(decoys);
        let ctx = MatchContext {
            segments: images.len(),
            area: 640.0 * 480.0,
            measurement_sigma: 1.0,
            search_sigmas: 3.0,
            min_probability: 0.01,
        };
        let frame = Brute { geometry: &geometry, camera: &cam, images, ctx, boost };
        let mut sigmas = [0.0; MAX_PARAMS];
        sigmas[..7].copy_from_slice(&[0.03, 0.03, 0.03, 0.01, 0.01, 0.01, 0.1]);
        let problem = Problem {
            geometry: &geometry,
            camera: &cam,
            centre,
            limits: &limits,
            prediction: &prediction,
            prior_sigmas: &sigmas,
            measurement_sigma: 1.0,
            reference_length: 0.0,
        };
        let p0 = crate::track::lowe::estimation::diagonal(&sigmas, 7);
        let mut segs = Vec::new();
        frame.model_segments(&prediction, &mut segs);
        let mut cands = Vec::new();
        frame.candidates(&segs, &p0, &mut cands);
        assert!(
            frame.boost.iter().all(|&(e, i)| cands.iter().any(|c| segs[c.model].edge == e && c.image == i)),
            "a planted decoy is not a candidate"
        );
        let outcome = search(&frame, &problem, segs, &cands, &settings());
        let error =
            outcome.solution.as_ref().map_or(f64::INFINITY, |s| vertex_error(&geometry, &cam, &s.state, &truth));
        (outcome, error)
    }

    /// With only true segments the first node is accepted and locking on
    /// brings in every edge and the true state.
    #[test]
    fn clean_frame_is_accepted_at_once_and_locks_on() {
        let (outcome, error) = run(Vec::new(), &[]);
        assert_eq!(outcome.branches, 1);
        assert!(outcome.lock_steps >= 1);
        assert_eq!(outcome.matches.len(), 16, "{:?}", outcome.matches.len());
        assert!(error < 0.1, "{error} px");
    }

    /// A decoy 8 px off edge 0, planted at the top of the ranking: the
    /// first node contains it and is rejected by its residual; the search
    /// backtracks and recovers the true state without the decoy.
    #[test]
    fn search_backtracks_from_a_decoy() {
        let geometry = hinged_box();
        let cam = camera();
        let truth_images = {
            let truth = State {
                pose: Pose::from_axis_angle(DVec3::new(0.5, -0.4, 0.1), DVec3::new(-0.12, 0.0, 0.8)),
                params: vec![0.9],
            };
            true_images(&geometry, &cam, &truth)
        };
        let [a, b] = truth_images[0];
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = dx.hypot(dy);
        let (nx, ny) = (-dy / len * 8.0, dx / len * 8.0);
        let decoy = [[a[0] + nx, a[1] + ny], [b[0] + nx, b[1] + ny]];
        let decoy_index = 16;
        let (outcome, error) = run(vec![(0, decoy_index)], &[decoy]);
        assert!(outcome.branches >= 2, "branches {}", outcome.branches);
        assert!(error < 0.1, "{error} px");
        assert!(outcome.matches.iter().all(|m| m.image != decoy_index));
    }

    fn flat_segment(edge: usize, a: [f64; 2], b: [f64; 2]) -> ModelSegment {
        let zero = [[0.0; MAX_PARAMS]; 2];
        ModelSegment { edge, interval: [0.0, 1.0], a, b, da: zero, db: zero, facing: 0 }
    }

    /// Image segments with a known contrast and model edges with a
    /// remembered one, and nothing else of a frame.
    struct Lines {
        images: Vec<Endpoints>,
        /// Direction across each image segment, bright side to dark side.
        contrasts: Vec<f64>,
        /// Remembered dark side of each model edge.
        remembered: Vec<f64>,
    }

    impl SearchFrame for Lines {
        fn model_segments(&self, _state: &State, out: &mut Vec<ModelSegment>) {
            out.clear();
        }
        fn candidates(&self, _segs: &[ModelSegment], _p: &Matrix, out: &mut Vec<Candidate>) {
            out.clear();
        }
        fn endpoints(&self, image: usize) -> Endpoints {
            self.images[image]
        }
        fn contrast_direction(&self, image: usize) -> Option<f64> {
            Some(self.contrasts[image]).filter(|d| d.is_finite())
        }
        fn remembered_contrast(&self, seg: &ModelSegment) -> f64 {
            self.remembered[seg.edge]
        }
        fn verify(&self, _segs: &[ModelSegment], _matches: &[Match], _residual_sigma: Option<f64>) -> Option<Support> {
            None
        }
        fn covered_length(&self, _segs: &[ModelSegment], _matches: &[Match]) -> f64 {
            0.0
        }
    }

    /// Of two image segments side by side on one model segment with
    /// opposite contrast, locking on leaves out the one whose contrast is
    /// not its edge's remembered one, near the line or not; pieces of
    /// opposite contrast one after the other, pieces of one contrast side
    /// by side, pieces farther apart than [`SIDE_BY_SIDE_PX`] and pieces of
    /// an edge with no remembered contrast all join.
    #[test]
    fn locking_on_leaves_out_a_piece_of_the_contrast_its_edge_has_not_shown() {
        use std::f64::consts::FRAC_PI_2;
        let (down, up) = (FRAC_PI_2, -FRAC_PI_2);
        let segs = vec![flat_segment(0, [0.0, 0.0], [100.0, 0.0]), flat_segment(1, [0.0, 40.0], [100.0, 40.0])];
        assert_eq!(segs[0].normal(), [0.0, 1.0]);
        let lines = Lines {
            images: vec![
                [[5.0, 0.3], [70.0, 0.2]],    // 0: on edge 0, dark below
                [[20.0, 2.6], [45.0, 2.8]],   // 1: 2.7 px below 0, dark above: left out
                [[75.0, -0.2], [98.0, -0.1]], // 2: after 0 along edge 0, dark above
                [[10.0, -2.5], [60.0, -2.5]], // 3: 2.5 px above 0, dark below
                [[0.0, 40.2], [90.0, 40.1]],  // 4: on edge 1, dark below
                [[30.0, 43.5], [60.0, 43.0]], // 5: 3.2 px below 4, dark above
                [[20.0, 12.0], [60.0, 12.0]], // 6: 11.8 px below 0, dark above
            ],
            contrasts: vec![down, up, up, down, down, up, up],
            remembered: vec![1.0, 0.0],
        };
        let cands: Vec<Candidate> = [(0, 0), (0, 1), (0, 2), (0, 3), (1, 4), (1, 5), (0, 6)]
            .iter()
            .map(|&(model, image)| Candidate { model, image, probability: 0.9 })
            .collect();
        let joined =
            |lines: &Lines| -> Vec<usize> { lock_set(lines, &segs, &cands, 0.5).iter().map(|m| m.image).collect() };
        assert_eq!(joined(&lines), vec![0, 2, 3, 4, 5, 6]);
        // The remembered contrast decides, not the distance: piece 1 now
        // lies on the line and piece 0 2 px off it.
        let mut nearer = lines;
        nearer.images[0] = [[5.0, 2.0], [70.0, 2.0]];
        nearer.images[1] = [[20.0, 0.1], [45.0, 0.1]];
        assert_eq!(joined(&nearer), vec![0, 2, 3, 4, 5, 6]);
        // Edge 0 remembered dark above: pieces 0 and 3, both dark below and
        // beside piece 1, go.
        let other = Lines { remembered: vec![-1.0, 0.0], ..nearer };
        assert_eq!(joined(&other), vec![1, 2, 4, 5, 6]);
        // Without a known contrast nothing is left out.
        let unknown = Lines { contrasts: vec![f64::NAN; 7], ..other };
        assert_eq!(joined(&unknown), vec![0, 1, 2, 3, 4, 5, 6]);
    }

    /// Only an unmatched segment nearly parallel to a matched one, beside
    /// it over half its length and more than coincident but less than the
    /// gap away pairs with it; nearest pairs first.
    #[test]
    fn parallel_neighbours_of_matched_segments() {
        let segs = vec![
            flat_segment(0, [0.0, 0.0], [100.0, 0.0]),   // matched
            flat_segment(1, [0.0, 3.0], [100.0, 3.0]),   // 3 px below: a pair
            flat_segment(2, [100.0, 0.3], [0.0, 0.3]),   // coincident (a hinge)
            flat_segment(3, [0.0, 20.0], [100.0, 20.0]), // beyond the gap
            flat_segment(4, [0.0, 2.0], [100.0, 60.0]),  // 30° off
            flat_segment(5, [80.0, 2.0], [200.0, 2.0]),  // beside it over 20 px only
            flat_segment(6, [10.0, -1.5], [90.0, -1.0]), // 1.5 px above, reversed ends: a pair
            flat_segment(0, [110.0, 2.0], [150.0, 2.0]), // another part of edge 0
        ];
        let matched =
            |seg: &ModelSegment| Match { edge: seg.edge, interval: seg.interval, endpoints: [seg.a, seg.b], image: 0 };
        let pairs = parallel_neighbours(&segs, &[matched(&segs[0])], 8.0);
        assert_eq!(pairs, vec![[0, 6], [0, 1]]);
        assert_eq!(parallel_neighbours(&segs, &[matched(&segs[0])], 2.5), vec![[0, 6]]);
        assert!(parallel_neighbours(&segs, &[], 8.0).is_empty());
    }
}
