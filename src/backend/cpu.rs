//! The CPU backend: the CPU twins of every stage, with buffers reused from
//! frame to frame so the per-frame loop does not allocate images.

use super::plan::{EdgelPart, FramePlan, Plane, PreviousFrame, SobelPart, SobelPlanes, Source, Step};
use super::{EarlyVision, FrameFeatures, FrameRequest, WindowRequest};
use crate::Result;
use crate::early::Feature;
use crate::early::compaction::compaction_cpu;
use crate::early::gaussian::gaussian_cpu;
use crate::early::ingest::ingest_cpu;
use crate::early::log::log_cpu;
use crate::early::sobel::{SobelOutput, SobelPixel, gradient_at_pixel, sobel_cpu, sobel_of_gradient};
use crate::early::temporal_diff;
use crate::early::window_energy;
use crate::early::zero_crossing::{Edgels, zero_crossing_strength_direction_cpu};
use crate::early::{cpf, edge_pyramid};
use crate::image::{FloatImage, GrayImage, RgbImage};

/// Early vision on the CPU (rayon threads across rows for large frames).
#[derive(Debug)]
pub struct CpuBackend {
    images: Images,
    tmp: FloatImage,
    tmp2: FloatImage,
    /// What `images.previous` holds, if it holds a usable previous frame.
    previous: Option<PreviousFrame>,
    /// For each Sobel set of this frame's plan that only compactions read as
    /// θ or magnitude, the plane its last [`Step::Sobel`] differentiated:
    /// those sets are evaluated at the listed pixels only (see [`listed_only`]).
    sparse_sobel: [Option<Plane>; 2],
    /// Scratch of [`fill_sobel_parts`].
    gradients: Vec<(f32, f32)>,
    /// Lists and pyramids handed back by [`EarlyVision::recycle`], refilled
    /// by the next frame (no per-frame allocation, no copy of the levels).
    spare: FrameFeatures,
}

/// The images a plan's steps read and write, one field per [`Plane`],
/// Sobel set and the edgels.
#[derive(Debug)]
struct Images {
    luma: FloatImage,
    smoothed: FloatImage,
    previous: FloatImage,
    motion_mask: FloatImage,
    sum: FloatImage,
    log: FloatImage,
    sobel_of_sum: SobelOutput,
    sobel_of_frame: SobelOutput,
    edgels: Edgels,
}

impl Images {
    fn new() -> Self {
        Self {
            luma: FloatImage::new(0, 0),
            smoothed: FloatImage::new(0, 0),
            previous: FloatImage::new(0, 0),
            motion_mask: FloatImage::new(0, 0),
            sum: FloatImage::new(0, 0),
            log: FloatImage::new(0, 0),
            sobel_of_sum: SobelOutput::new(0, 0),
            sobel_of_frame: SobelOutput::new(0, 0),
            edgels: Edgels::new(0, 0),
        }
    }

    fn sobel(&self, set: SobelPlanes) -> &SobelOutput {
        match set {
            SobelPlanes::OfSum => &self.sobel_of_sum,
            SobelPlanes::OfFrame => &self.sobel_of_frame,
        }
    }

    fn source(&self, source: Source) -> &FloatImage {
        match source {
            Source::Plane(p) => {
                plane(&self.luma, &self.smoothed, &self.previous, &self.motion_mask, &self.sum, &self.log, p)
            }
            Source::Sobel(set, part) => {
                let s = self.sobel(set);
                match part {
                    SobelPart::Gx => &s.gx,
                    SobelPart::Gy => &s.gy,
                    SobelPart::Magnitude => &s.magnitude,
                    SobelPart::Direction => &s.direction,
                    SobelPart::Theta => &s.theta,
                }
            }
            Source::Edgels(EdgelPart::Strength) => &self.edgels.strength,
            Source::Edgels(EdgelPart::Direction) => &self.edgels.direction,
        }
    }

    fn sobel_mut(&mut self, set: SobelPlanes) -> &mut SobelOutput {
        match set {
            SobelPlanes::OfSum => &mut self.sobel_of_sum,
            SobelPlanes::OfFrame => &mut self.sobel_of_frame,
        }
    }

    /// Sobel of plane `input` into set `output` (disjoint fields of `self`).
    fn sobel_into(&mut self, input: Plane, output: SobelPlanes) {
        let Self { luma, smoothed, previous, motion_mask, sum, log, sobel_of_sum, sobel_of_frame, .. } = self;
        let src = plane(luma, smoothed, previous, motion_mask, sum, log, input);
        let dst = match output {
            SobelPlanes::OfSum => sobel_of_sum,
            SobelPlanes::OfFrame => sobel_of_frame,
        };
        sobel_cpu(src, dst);
    }
}

/// The image of `p` among the single planes.
fn plane<'a>(
    luma: &'a FloatImage,
    smoothed: &'a FloatImage,
    previous: &'a FloatImage,
    motion_mask: &'a FloatImage,
    sum: &'a FloatImage,
    log: &'a FloatImage,
    p: Plane,
) -> &'a FloatImage {
    match p {
        Plane::Luma => luma,
        Plane::Smoothed => smoothed,
        Plane::Previous => previous,
        Plane::MotionMask => motion_mask,
        Plane::Sum => sum,
        Plane::Log => log,
    }
}

impl Default for CpuBackend {
    fn default() -> Self {
        Self::new()
    }
}

impl CpuBackend {
    /// A CPU backend with empty buffers (they grow on the first frame).
    #[must_use]
    pub fn new() -> Self {
        Self {
            images: Images::new(),
            tmp: FloatImage::new(0, 0),
            tmp2: FloatImage::new(0, 0),
            previous: None,
            sparse_sobel: [None; 2],
            gradients: Vec::new(),
            spare: FrameFeatures::default(),
        }
    }
}

impl EarlyVision for CpuBackend {
    fn name(&self) -> String {
        format!("CPU ({} threads)", rayon::current_num_threads())
    }

    fn reset(&mut self) {
        self.previous = None;
    }

    fn recycle(&mut self, features: FrameFeatures) {
        // Pyramids kept here (`Pyramids::Keep`) stay when the features handed
        // back carry none, so the next frame refills them instead of allocating.
        let kept = self.spare.pyramids.take();
        self.spare = features;
        if self.spare.pyramids.is_none() {
            self.spare.pyramids = kept;
        }
    }

    fn process(&mut self, frame: &GrayImage, request: &FrameRequest) -> Result<FrameFeatures> {
        self.run(frame, None, request)
    }

    fn process_rgb(&mut self, frame: &RgbImage, request: &FrameRequest) -> Result<FrameFeatures> {
        self.run(&frame.to_gray(), Some(frame), request)
    }
}

impl CpuBackend {
    /// One frame: the grey stages on `frame`, the sample windows on
    /// `colour` (or on `frame` as colour without hue when there is none).
    fn run(&mut self, frame: &GrayImage, colour: Option<&RgbImage>, request: &FrameRequest) -> Result<FrameFeatures> {
        request.validate()?;
        let (w, h) = frame.size();
        let plan = FramePlan::new(request, w, h, self.previous.as_ref());
        let mut out = FrameFeatures::default();
        let img = &mut self.images;
        ingest_cpu(frame, &mut img.luma);
        for (i, step) in plan.steps().iter().enumerate() {
            let last_step = i + 1 == plan.steps().len();
            match *step {
                Step::Smooth(p) => gaussian_cpu(&img.luma, &p, &mut self.tmp, &mut img.smoothed)?,
                // 000 eq. 1: G*_t − G*_{t+1}, thresholded, and the sum of both
                // for eq. 2, fused into one pass over the two frames.
                Step::DiffAndSum(p) => temporal_diff::temporal_diff_and_sum_cpu(
                    &img.previous,
                    &img.smoothed,
                    &p,
                    &mut img.motion_mask,
                    &mut img.sum,
                )?,
                Step::Sobel { input, output } => {
                    let sparse = listed_only(&plan, output);
                    self.sparse_sobel[sobel_slot(output)] = sparse.then_some(input);
                    if !sparse {
                        img.sobel_into(input, output);
                    }
                }
                Step::Log(p) => log_cpu(&img.luma, &p, &mut self.tmp, &mut self.tmp2, &mut img.log)?,
                // Steps read the edgels' strength and direction only
                // (`EdgelPart`): the offsets are not computed.
                Step::ZeroCrossings(p) => zero_crossing_strength_direction_cpu(
                    &img.log,
                    &p,
                    &mut img.edgels.strength,
                    &mut img.edgels.direction,
                ),
                Step::Compact { list, select, theta, magnitude, params } => {
                    let mut features = recycled_list(self.spare.list_mut(list));
                    let sparse = |source| match source {
                        Source::Sobel(set, part) => self.sparse_sobel[sobel_slot(set)].map(|plane| (plane, part)),
                        _ => None,
                    };
                    let (sparse_theta, sparse_magnitude) = (sparse(theta), sparse(magnitude));
                    // A sparse set has no planes: list `select` in their place, then fill in.
                    let dense = |source, sparse: Option<_>| img.source(if sparse.is_some() { select } else { source });
                    compaction_cpu(
                        img.source(select),
                        dense(theta, sparse_theta),
                        dense(magnitude, sparse_magnitude),
                        &params,
                        &mut features,
                    )?;
                    let plane = |p| img.source(Source::Plane(p));
                    match (sparse_theta, sparse_magnitude) {
                        (Some((pt, t)), Some((pm, m))) if pt == pm => {
                            fill_sobel_parts(plane(pt), &mut features, Some(t), Some(m), &mut self.gradients);
                        }
                        (theta, magnitude) => {
                            if let Some((pt, t)) = theta {
                                fill_sobel_parts(plane(pt), &mut features, Some(t), None, &mut self.gradients);
                            }
                            if let Some((pm, m)) = magnitude {
                                fill_sobel_parts(plane(pm), &mut features, None, Some(m), &mut self.gradients);
                            }
                        }
                    }
                    *out.list_mut(list) = Some(features);
                }
                Step::EmptyList(list) => *out.list_mut(list) = Some(recycled_list(self.spare.list_mut(list))),
                Step::Pyramids { gradient, returned } => {
                    // Computed straight into the levels handed out (recycled
                    // ones when the caller gave them back): no copy of every level.
                    let (mut cpf_levels, mut edge_levels) = self.spare.pyramids.take().unwrap_or_default();
                    if !returned {
                        // Kept here, where nothing reads them: the CPF levels
                        // 0, four copies of the frame, are not made.
                        cpf::cpf_cpu_coarser_levels(&img.luma, &mut cpf_levels);
                    }
                    if last_step {
                        // Nothing reads the frame or its gradient after this
                        // step: they move into level 0 instead of being copied
                        // (the next frame overwrites the buffers they leave).
                        if returned {
                            cpf::cpf_cpu_taking(&mut img.luma, &mut cpf_levels);
                        }
                        let g = img.sobel_mut(gradient);
                        edge_pyramid::edge_pyramid_cpu_taking(&mut g.gx, &mut g.gy, &mut edge_levels)?;
                    } else {
                        if returned {
                            cpf::cpf_cpu(&img.luma, &mut cpf_levels);
                        }
                        let g = img.sobel(gradient);
                        edge_pyramid::edge_pyramid_cpu(&g.gx, &g.gy, &mut edge_levels)?;
                    }
                    if returned {
                        out.pyramids = Some((cpf_levels, edge_levels));
                    } else {
                        self.spare.pyramids = Some((cpf_levels, edge_levels));
                    }
                }
                Step::Windows { .. } => {
                    let from_gray;
                    let rgb = match colour {
                        Some(c) => c,
                        None => {
                            from_gray = RgbImage::from_gray(frame);
                            &from_gray
                        }
                    };
                    match &request.windows {
                        Some(WindowRequest::Features { params, windows }) => {
                            out.window_features = Some(window_energy::window_features_cpu(rgb, params, windows)?);
                        }
                        Some(WindowRequest::Energies { windows, template }) => {
                            out.window_energies = Some(window_energy::window_energy_cpu(rgb, windows, template)?);
                        }
                        None => {}
                    }
                }
            }
        }
        // This frame's smoothed image becomes the next frame's previous one
        // when the plan says so; the swapped-out buffer is overwritten by the
        // next smoothing.
        self.previous = plan.next_previous();
        if self.previous.is_some() {
            std::mem::swap(&mut img.previous, &mut img.smoothed);
        }
        Ok(out)
    }
}

/// Whether the plan reads Sobel set `set` only as the θ or magnitude of
/// listed pixels (never as a compaction's `select`, nor as the pyramids'
/// gradient): then the CPU computes it at the listed pixels alone, with
/// [`crate::early::sobel::sobel_at`], bit for bit what the full planes would
/// hold there. The motion list's Sobel of the frame sum is such a set: it is
/// needed only where the motion mask is set.
fn listed_only(plan: &FramePlan, set: SobelPlanes) -> bool {
    plan.steps().iter().all(|step| match *step {
        Step::Compact { select: Source::Sobel(s, _), .. } => s != set,
        Step::Pyramids { gradient, .. } => gradient != set,
        _ => true,
    })
}

/// Set each feature's θ and magnitude, where a part is given, to that part
/// of the Sobel values of `src` at the feature's pixel
/// ([`crate::early::sobel::sobel_at`], bit for bit). Two passes: the
/// gradients, gathered pixel by pixel into `gradients` (scratch, reused),
/// then the magnitudes and angles in one loop that vectorises.
fn fill_sobel_parts(
    src: &FloatImage,
    features: &mut [Feature],
    theta: Option<SobelPart>,
    magnitude: Option<SobelPart>,
    gradients: &mut Vec<(f32, f32)>,
) {
    gradients.clear();
    gradients.extend(features.iter().map(|f| gradient_at_pixel(src, f.x as usize, f.y as usize)));
    let pick = |part: Option<SobelPart>, p: &SobelPixel, kept: f32| part.map_or(kept, |part| sobel_part(p, part));
    for (f, &(gx, gy)) in features.iter_mut().zip(gradients.iter()) {
        let p = sobel_of_gradient(gx, gy);
        (f.theta, f.magnitude) = (pick(theta, &p, f.theta), pick(magnitude, &p, f.magnitude));
    }
}

/// Index of a Sobel set in [`CpuBackend`]'s per-set arrays.
fn sobel_slot(set: SobelPlanes) -> usize {
    match set {
        SobelPlanes::OfSum => 0,
        SobelPlanes::OfFrame => 1,
    }
}

/// One of the five values of a Sobel pixel.
fn sobel_part(p: &SobelPixel, part: SobelPart) -> f32 {
    match part {
        SobelPart::Gx => p.gx,
        SobelPart::Gy => p.gy,
        SobelPart::Magnitude => p.magnitude,
        SobelPart::Direction => p.direction,
        SobelPart::Theta => p.theta,
    }
}

/// An empty list, reusing a recycled allocation when there is one.
fn recycled_list(spare: &mut Option<Vec<Feature>>) -> Vec<Feature> {
    let mut list = spare.take().unwrap_or_default();
    list.clear();
    list
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testimage::natural;

    /// The motion list, whose θ and magnitude the backend computes at the
    /// listed pixels only, equals the list compacted from the dense Sobel
    /// planes of the frame sum, bit for bit.
    #[test]
    fn motion_list_from_listed_pixels_equals_the_dense_planes() {
        use crate::early::compaction::compaction;
        use crate::early::gaussian::gaussian;
        use crate::early::sobel::sobel;
        let (w, h) = (40, 30);
        let base = natural(w + 4, h, 5);
        let frames: Vec<GrayImage> = (0..2).map(|k| GrayImage::from_fn(w, h, |x, y| base.get(x + 2 * k, y))).collect();
        let request = FrameRequest::full_chain(w, h);
        let mut backend = CpuBackend::new();
        backend.process(&frames[0], &request).unwrap();
        let got = backend.process(&frames[1], &request).unwrap().motion.unwrap();

        let motion = request.motion.unwrap();
        let smooth = |f: &GrayImage| gaussian(&f.to_f32(), &request.smoothing).unwrap();
        let (mut mask, mut sum) = (FloatImage::new(0, 0), FloatImage::new(0, 0));
        let (previous, current) = (smooth(&frames[0]), smooth(&frames[1]));
        temporal_diff::temporal_diff_and_sum_cpu(&previous, &current, &motion.diff, &mut mask, &mut sum).unwrap();
        let planes = sobel(&sum);
        // The plan lists mask pixels above one half.
        let expected = compaction(&mask, &planes.theta, &planes.magnitude, &motion.list.compaction(0.5)).unwrap();
        assert!(!expected.is_empty());
        let bits =
            |l: &[Feature]| l.iter().map(|f| (f.x, f.y, f.theta.to_bits(), f.magnitude.to_bits())).collect::<Vec<_>>();
        assert_eq!(bits(&got), bits(&expected));
    }

    /// Recycled lists and pyramid levels are refilled, not appended to: a
    /// backend fed its own features back answers as one that is not.
    #[test]
    fn recycling_features_changes_nothing() {
        let (w, h) = (40, 30);
        let base = natural(w + 3, h, 7);
        let frames: Vec<GrayImage> = (0..3).map(|k| GrayImage::from_fn(w, h, |x, y| base.get(x + k, y))).collect();
        let request = FrameRequest::full_chain(w, h);
        let (mut fresh, mut recycling) = (CpuBackend::new(), CpuBackend::new());
        for f in &frames {
            let expected = fresh.process(f, &request).unwrap();
            let got = recycling.process(f, &request).unwrap();
            assert_eq!(got, expected);
            recycling.recycle(got);
        }
    }
}
