//! The CPU backend: the CPU twins of every stage, with buffers reused from
//! frame to frame so the per-frame loop does not allocate images.
//!
//! A stage whose outputs only windowed lists read runs on the part of the
//! frame those windows need, when that is less than the frame: the LoG and
//! its zero crossings ([`log_region`]), the smoothing, the motion step and
//! the Sobel sets made from them ([`smoothing_region`]), a Sobel set's
//! gradients and magnitude ([`dense_region`]). Inside the part every value
//! is the whole frame's, bit for bit, so the lists are those of the GPU
//! backend, which computes whole frames but for the LoG and its zero
//! crossings (computed there around the same windows).

use super::plan::{EdgelPart, FramePlan, Plane, PreviousFrame, SobelPart, SobelPlanes, Source, Step};
use super::{EarlyVision, FrameFeatures, FrameRequest, WindowRequest};
use crate::Result;
use crate::early::compaction::CompactionParams;
use crate::early::compaction::compaction_cpu;
use crate::early::gaussian::{gaussian_cpu, gaussian_region_cpu};
use crate::early::ingest::{ingest_cpu, ingest_part_cpu};
use crate::early::log::log_cpu;
use crate::early::log::log_kernels;
use crate::early::sobel::{
    SobelOutput, SobelPixel, gradient_at_pixel, sobel_cpu, sobel_gradient_magnitude_region_cpu, sobel_of_gradient,
};
use crate::early::temporal_diff;
use crate::early::window_energy;
use crate::early::zero_crossing::{Edgels, zero_crossing_strength_direction_cpu};
use crate::early::{Feature, Window};
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
    /// Where `images.previous` holds the previous frame smoothed: `None`
    /// for the whole frame, a window when that frame was smoothed there
    /// only ([`smoothing_region`]); `images.previous_luma` then holds that
    /// frame, to smooth elsewhere when this frame needs it.
    previous_part: Option<Window>,
    /// Whether the smoothing and the motion step may run on a window of
    /// the frame ([`smoothing_region`]); off only to test that they give
    /// the whole frame's lists.
    windowed: bool,
    /// Scratch of [`gaussian_region_cpu`].
    piece: Vec<f32>,
    /// For each Sobel set of this frame's plan, the plane its last
    /// [`Step::Sobel`] differentiated and how much of it is whole planes
    /// (see [`sobel_need`]); the parts not in planes are evaluated at the
    /// listed pixels only.
    sparse_sobel: [Option<(Plane, SobelNeed)>; 2],
    /// Scratch of [`fill_sobel_parts`].
    gradients: Vec<(f32, f32)>,
    /// Lists and pyramids handed back by [`EarlyVision::recycle`], refilled
    /// by the next frame (no per-frame allocation, no copy of the levels).
    spare: FrameFeatures,
    /// The frame's part the LoG is computed on when only windowed lists
    /// read it (see [`log_region`]).
    log_source: FloatImage,
}

/// The images a plan's steps read and write, one field per [`Plane`],
/// Sobel set and the edgels.
#[derive(Debug)]
struct Images {
    luma: FloatImage,
    smoothed: FloatImage,
    previous: FloatImage,
    previous_luma: FloatImage,
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
            previous_luma: FloatImage::new(0, 0),
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

    /// The five Sobel planes of plane `input` into set `output`.
    fn sobel_into(&mut self, input: Plane, output: SobelPlanes) {
        let (src, dst) = self.sobel_source_and_set(input, output);
        sobel_cpu(src, dst);
    }

    /// The gradients and magnitude of `input` into `output`, inside `region`.
    fn gradient_magnitude_into(&mut self, input: Plane, output: SobelPlanes, region: Window) {
        let (src, dst) = self.sobel_source_and_set(input, output);
        sobel_gradient_magnitude_region_cpu(src, region, dst);
    }

    /// Plane `input` and set `output` (disjoint fields of `self`).
    fn sobel_source_and_set(&mut self, input: Plane, output: SobelPlanes) -> (&FloatImage, &mut SobelOutput) {
        let Self { luma, smoothed, previous, motion_mask, sum, log, sobel_of_sum, sobel_of_frame, .. } = self;
        let src = plane(luma, smoothed, previous, motion_mask, sum, log, input);
        let dst = match output {
            SobelPlanes::OfSum => sobel_of_sum,
            SobelPlanes::OfFrame => sobel_of_frame,
        };
        (src, dst)
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
            previous_part: None,
            windowed: true,
            piece: Vec::new(),
            sparse_sobel: [None; 2],
            gradients: Vec::new(),
            spare: FrameFeatures::default(),
            log_source: FloatImage::new(0, 0),
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
        // The LoG and its edgels, when computed on a part of the frame, are
        // that part's size, and the lists reading them are offset by its corner.
        let log_part = log_region(&plan, w, h);
        // The smoothing and the motion step run on the part of the frame
        // their outputs are read in, when that is less than half the frame.
        let full = Window::full(w, h);
        let smoothing_part = match smoothing_region(&plan, w, h) {
            part if self.windowed && 2 * part.area() < full.area() => Some(part),
            _ => None,
        };
        // The frame itself is kept for the next frame's motion step when
        // this one smooths a part of it only.
        let keeps_luma = smoothing_part.is_some() && plan.next_previous().is_some();
        // The frame as f32 is made before the first step that reads it (the
        // LoG of a part converts its part itself): a plan of such a LoG
        // alone converts that part only.
        let ingest_before = plan.steps().iter().position(|step| {
            step.reads().contains(&Source::Plane(Plane::Luma)) && !(matches!(step, Step::Log(_)) && log_part.is_some())
        });
        for (i, step) in plan.steps().iter().enumerate() {
            let last_step = i + 1 == plan.steps().len();
            if ingest_before == Some(i) {
                ingest_cpu(frame, &mut img.luma);
            }
            match *step {
                Step::Smooth(p) => match smoothing_part {
                    Some(part) => {
                        gaussian_region_cpu(&img.luma, &p, part, &mut self.tmp, &mut self.piece, &mut img.smoothed)?;
                    }
                    None => gaussian_cpu(&img.luma, &p, &mut self.tmp, &mut img.smoothed)?,
                },
                // 000 eq. 1: G*_t − G*_{t+1}, thresholded, and the sum of both
                // for eq. 2, fused into one pass over the two frames.
                Step::DiffAndSum(p) => {
                    // The previous frame smoothed where this frame needs it.
                    let needed = smoothing_part.unwrap_or(full);
                    if self.previous_part.is_some_and(|had| !had.contains(&needed)) {
                        let (src, tmp, piece) = (&img.previous_luma, &mut self.tmp, &mut self.piece);
                        gaussian_region_cpu(src, &request.smoothing, needed, tmp, piece, &mut img.previous)?;
                    }
                    let (prev, cur, mask, sum) = (&img.previous, &img.smoothed, &mut img.motion_mask, &mut img.sum);
                    temporal_diff::temporal_diff_and_sum_cpu(prev, cur, &p, needed, mask, sum)?;
                }
                Step::Sobel { input, output } => {
                    let need = sobel_need(&plan, output);
                    self.sparse_sobel[sobel_slot(output)] = Some((input, need));
                    match need {
                        SobelNeed::Listed => {}
                        SobelNeed::GradientMagnitude => {
                            img.gradient_magnitude_into(input, output, dense_region(&plan, output, w, h));
                        }
                        SobelNeed::Planes => img.sobel_into(input, output),
                    }
                }
                Step::Log(p) => match log_part {
                    Some(part) => {
                        ingest_part_cpu(frame, part, &mut self.log_source);
                        log_cpu(&self.log_source, &p, &mut self.tmp, &mut self.tmp2, &mut img.log)?;
                    }
                    None => log_cpu(&img.luma, &p, &mut self.tmp, &mut self.tmp2, &mut img.log)?,
                },
                // Steps read the edgels' strength and direction only
                // (`EdgelPart`): the offsets are not computed.
                Step::ZeroCrossings(p) => zero_crossing_strength_direction_cpu(
                    &img.log,
                    &p,
                    &mut img.edgels.strength,
                    &mut img.edgels.direction,
                ),
                Step::Compact { list, select, theta, magnitude, params }
                    if log_part.is_some() && select.reads_log() =>
                {
                    let part = log_part.unwrap_or_default();
                    let mut features = recycled_list(self.spare.list_mut(list));
                    let window = params.window.clipped(w, h);
                    let local = Window {
                        x0: window.x0.max(part.x0) - part.x0,
                        y0: window.y0.max(part.y0) - part.y0,
                        x1: window.x1.min(part.x1).max(part.x0) - part.x0,
                        y1: window.y1.min(part.y1).max(part.y0) - part.y0,
                    };
                    let params = CompactionParams { window: local, ..params };
                    compaction_cpu(
                        img.source(select),
                        img.source(theta),
                        img.source(magnitude),
                        &params,
                        &mut features,
                    )?;
                    for f in &mut features {
                        f.x += part.x0;
                        f.y += part.y0;
                    }
                    *out.list_mut(list) = Some(features);
                }
                Step::Compact { list, select, theta, magnitude, params } => {
                    let mut features = recycled_list(self.spare.list_mut(list));
                    let sparse = |source| match source {
                        Source::Sobel(set, part) => match self.sparse_sobel[sobel_slot(set)] {
                            Some((plane, SobelNeed::Listed)) => Some((plane, part)),
                            Some((plane, SobelNeed::GradientMagnitude)) if is_angle(part) => Some((plane, part)),
                            _ => None,
                        },
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
                    // When nothing reads the frame or its gradient after this
                    // step, they move into level 0 instead of being copied
                    // (the next frame overwrites the buffers they leave); the
                    // frame stays when it is kept as the previous one.
                    if returned {
                        if last_step && !keeps_luma {
                            cpf::cpf_cpu_taking(&mut img.luma, &mut cpf_levels);
                        } else {
                            cpf::cpf_cpu(&img.luma, &mut cpf_levels);
                        }
                    }
                    if last_step {
                        let g = img.sobel_mut(gradient);
                        edge_pyramid::edge_pyramid_cpu_taking(&mut g.gx, &mut g.gy, &mut edge_levels)?;
                    } else {
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
            if keeps_luma {
                std::mem::swap(&mut img.previous_luma, &mut img.luma);
            }
            self.previous_part = smoothing_part;
        }
        Ok(out)
    }
}

/// The part of a `width`×`height` frame the LoG and its zero crossings need
/// to be computed on, when that is less than the frame: the windows of the
/// lists reading them ([`FramePlan::log_windows`]) grown by the LoG's
/// radius plus the zero crossings' one pixel. Inside the windows the values
/// are bit for bit those of the whole frame: every pixel a window's LoG or
/// crossing reads lies in the part, and the part's borders clamp only where
/// they are the frame's own.
fn log_region(plan: &FramePlan, width: usize, height: usize) -> Option<Window> {
    let radius = plan.steps().iter().find_map(|step| match *step {
        Step::Log(p) => log_kernels(p.sigma).ok().map(|k| k.radius() as u32),
        _ => None,
    })?;
    let union = plan.log_windows(width, height)?;
    if union.is_empty() {
        return None;
    }
    let part = union.grown(radius + 1).clipped(width, height);
    (part.area() < width * height).then_some(part)
}

/// How much of a Sobel set the CPU computes as whole planes.
#[derive(Clone, Copy, Debug, PartialEq)]
enum SobelNeed {
    /// No planes: every part read is evaluated at the listed pixels.
    Listed,
    /// gx, gy and magnitude planes; the angles at the listed pixels.
    GradientMagnitude,
    /// All five planes.
    Planes,
}

/// Whether `part` is one of a Sobel set's angles.
fn is_angle(part: SobelPart) -> bool {
    matches!(part, SobelPart::Direction | SobelPart::Theta)
}

/// How the plan reads Sobel set `set`. Read only as the θ or magnitude of
/// listed pixels (never as a compaction's `select`, nor as the pyramids'
/// gradient), the CPU computes it at the listed pixels alone
/// ([`SobelNeed::Listed`]), with [`crate::early::sobel::sobel_at`], bit for
/// bit what the full planes would hold there: the motion list's Sobel of the
/// frame sum is such a set, needed only where the motion mask is set. With
/// no compaction selecting on its angles, the angles are likewise evaluated
/// at the listed pixels only ([`SobelNeed::GradientMagnitude`]): the edge
/// list selects on the magnitude and reads the direction of the pixels it
/// keeps, the pyramids read gx and gy.
fn sobel_need(plan: &FramePlan, set: SobelPlanes) -> SobelNeed {
    let steps = plan.steps();
    let selects = |angle: Option<bool>| {
        steps.iter().any(|step| match *step {
            Step::Compact { select: Source::Sobel(s, part), .. } => {
                s == set && angle.is_none_or(|a| is_angle(part) == a)
            }
            _ => false,
        })
    };
    let pyramids = steps.iter().any(|step| matches!(*step, Step::Pyramids { gradient, .. } if gradient == set));
    if selects(Some(true)) {
        SobelNeed::Planes
    } else if selects(None) || pyramids {
        SobelNeed::GradientMagnitude
    } else {
        SobelNeed::Listed
    }
}

/// Where this frame's smoothed image is read, directly or through the
/// images made from it (the previous frame's, the motion mask, the frame
/// sum and their Sobel sets): the bounding box of the windows of the
/// compactions reading those images, grown by the one pixel a Sobel step
/// reads around each of its pixels. The whole frame when any other step
/// reads them (the pyramids, through a Sobel set). Inside the region every
/// value a list reads is computed from values inside it, and each equals
/// the whole frame's bit for bit.
fn smoothing_region(plan: &FramePlan, width: usize, height: usize) -> Window {
    let full = Window::full(width, height);
    let smoothing = |p: Plane| matches!(p, Plane::Smoothed | Plane::Previous | Plane::MotionMask | Plane::Sum);
    let mut region = Window::default();
    for step in plan.steps() {
        let part = match *step {
            Step::Smooth(_) | Step::DiffAndSum(_) => continue,
            Step::Sobel { input, output } if smoothing(input) => {
                dense_region(plan, output, width, height).grown(1).clipped(width, height)
            }
            Step::Compact { select, theta, magnitude, params, .. }
                if [select, theta, magnitude].iter().any(|s| matches!(*s, Source::Plane(p) if smoothing(p))) =>
            {
                params.window.clipped(width, height)
            }
            ref other if other.reads().iter().any(|s| matches!(*s, Source::Plane(p) if smoothing(p))) => full,
            _ => continue,
        };
        region = region.union(&part);
    }
    region
}

/// Where the dense planes of Sobel set `set` are read: the bounding box of
/// the windows of the compactions reading them, or the whole frame when the
/// pyramids read them too. Nothing else reads a Sobel set.
fn dense_region(plan: &FramePlan, set: SobelPlanes, width: usize, height: usize) -> Window {
    let mut region = Window::default();
    for step in plan.steps() {
        match *step {
            Step::Pyramids { gradient, .. } if gradient == set => return Window::full(width, height),
            Step::Compact { select, theta, magnitude, params, .. }
                if [select, theta, magnitude].iter().any(|s| matches!(*s, Source::Sobel(s, _) if s == set)) =>
            {
                region = region.union(&params.window.clipped(width, height));
            }
            _ => {}
        }
    }
    region
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

    /// A list's pixels and the bits of their values.
    fn bits(list: &[Feature]) -> Vec<(u32, u32, u32, u32)> {
        list.iter().map(|f| (f.x, f.y, f.theta.to_bits(), f.magnitude.to_bits())).collect()
    }

    /// Windows of a 97×61 frame at awkward places: inside, at the first and
    /// the last corner, one row, one column, one pixel, empty, and reaching
    /// beyond the frame.
    const AWKWARD_WINDOWS: [Window; 8] = [
        Window { x0: 20, y0: 15, x1: 61, y1: 40 },
        Window { x0: 0, y0: 0, x1: 13, y1: 9 },
        Window { x0: 80, y0: 50, x1: 97, y1: 61 },
        Window { x0: 0, y0: 30, x1: 97, y1: 31 },
        Window { x0: 45, y0: 0, x1: 46, y1: 61 },
        Window { x0: 33, y0: 22, x1: 34, y1: 23 },
        Window { x0: 50, y0: 20, x1: 50, y1: 40 },
        Window { x0: 90, y0: 55, x1: 200, y1: 300 },
    ];
    use crate::early::temporal_diff::TemporalDiffParams;
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
        temporal_diff::temporal_diff_and_sum_cpu(
            &previous,
            &current,
            &motion.diff,
            Window::full(w, h),
            &mut mask,
            &mut sum,
        )
        .unwrap();
        let planes = sobel(&sum);
        // The plan lists mask pixels above one half.
        let expected = compaction(&mask, &planes.theta, &planes.magnitude, &motion.list.compaction(0.5)).unwrap();
        assert!(!expected.is_empty());
        assert_eq!(bits(&got), bits(&expected));
    }

    /// The edge list, selected on the magnitude plane with its direction
    /// computed at the listed pixels only, equals the list compacted from
    /// the five dense Sobel planes, bit for bit, of the raw and the smoothed
    /// frame, on an odd size.
    #[test]
    fn edge_list_with_listed_directions_equals_the_dense_planes() {
        use crate::early::compaction::compaction;
        use crate::early::gaussian::gaussian;
        use crate::early::sobel::sobel;
        let (w, h) = (41, 27);
        let frame = natural(w, h, 9);
        for smoothed in [false, true] {
            let mut request = FrameRequest::full_chain(w, h);
            let mut edges = request.edges.unwrap();
            edges.smoothed = smoothed;
            request.edges = Some(edges);
            let got = CpuBackend::new().process(&frame, &request).unwrap().edges.unwrap();

            let luma = frame.to_f32();
            let src = if smoothed { gaussian(&luma, &request.smoothing).unwrap() } else { luma };
            let planes = sobel(&src);
            let compacted = compaction(
                &planes.magnitude,
                &planes.direction,
                &planes.magnitude,
                &edges.list.compaction(edges.threshold),
            );
            let expected = compacted.unwrap();
            assert!(!expected.is_empty());
            assert_eq!(bits(&got), bits(&expected), "smoothed {smoothed}");
        }
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

    /// Motion and edge lists computed on a part of the frame (the smoothing,
    /// the motion step and the Sobel sets only where the lists read them)
    /// equal those of the whole-frame computation, bit for bit, over a
    /// sequence whose windows move, shrink to a pixel, touch each border, go
    /// empty and cover the frame, with the edges of the raw or the smoothed
    /// frame, pyramids on some frames and a frame without motion.
    #[test]
    fn lists_of_windows_equal_the_whole_frame_computations() {
        use crate::backend::{EdgeRequest, ListSpec, MotionRequest, Pyramids};
        let (w, h) = (97, 61);
        let base = natural(w + 60, h + 4, 13);
        let frames: Vec<GrayImage> =
            (0..16).map(|k| GrayImage::from_fn(w, h, |x, y| base.get(x + 3 * k + (k % 3), y + k % 4))).collect();
        // The awkward windows, the whole frame and two more of a third of it.
        let windows: Vec<Window> = AWKWARD_WINDOWS
            .into_iter()
            .chain([
                Window::full(w, h),
                Window { x0: 30, y0: 10, x1: 60, y1: 35 },
                Window { x0: 25, y0: 12, x1: 58, y1: 44 },
            ])
            .collect();
        let list = |window| ListSpec { window, cap: None, seed: 0 };
        let (mut parts, mut whole) = (CpuBackend::new(), CpuBackend::new());
        whole.windowed = false;
        let bits = |l: &Option<Vec<Feature>>| bits(l.as_deref().unwrap_or_default());
        let mut motion_pixels = 0;
        for (k, frame) in frames.iter().enumerate() {
            let request = FrameRequest {
                motion: (k != 11).then(|| MotionRequest {
                    diff: TemporalDiffParams { threshold: 2.0 },
                    list: list(windows[k % windows.len()]),
                }),
                edges: Some(EdgeRequest {
                    threshold: 30.0,
                    smoothed: k % 4 != 3,
                    list: list(windows[(k + 3) % windows.len()]),
                }),
                pyramids: if [3, 6, 7].contains(&k) { Pyramids::Return } else { Pyramids::Off },
                ..FrameRequest::default()
            };
            let got = parts.process(frame, &request).unwrap();
            let expected = whole.process(frame, &request).unwrap();
            assert_eq!(bits(&got.motion), bits(&expected.motion), "frame {k}: motion");
            assert_eq!(bits(&got.edges), bits(&expected.edges), "frame {k}: edges");
            motion_pixels += expected.motion.map_or(0, |m| m.len());
        }
        assert!(motion_pixels > 500, "{motion_pixels} motion pixels");
    }

    /// The zero-crossing list of a window, computed on the window's part of
    /// the frame only, equals the whole frame's list cut to the window, bit
    /// for bit: windows inside, at each border, one pixel, empty, odd sizes.
    #[test]
    fn zero_crossings_of_a_window_equal_the_whole_frames_in_it() {
        use crate::backend::{ListSpec, ZeroCrossingRequest};
        use crate::early::log::LogParams;
        use crate::early::zero_crossing::ZeroCrossingParams;
        let (w, h) = (97, 61);
        let frame = natural(w, h, 11);
        let request = |window: Window| FrameRequest {
            zero_crossings: Some(ZeroCrossingRequest {
                log: LogParams { sigma: 1.2 },
                crossings: ZeroCrossingParams { min_slope: 0.5 },
                list: ListSpec { window, cap: None, seed: 0 },
            }),
            ..FrameRequest::default()
        };
        let mut backend = CpuBackend::new();
        let whole = backend.process(&frame, &request(Window::full(w, h))).unwrap().zero_crossings.unwrap();
        assert!(whole.len() > 200, "{} crossings", whole.len());
        for window in AWKWARD_WINDOWS {
            assert!(log_region(&FramePlan::new(&request(window), w, h, None), w, h).is_some() || window.is_empty());
            let got = backend.process(&frame, &request(window)).unwrap().zero_crossings.unwrap();
            let inside = |f: &&Feature| f.x >= window.x0 && f.x < window.x1 && f.y >= window.y0 && f.y < window.y1;
            let expected: Vec<Feature> = whole.iter().filter(inside).copied().collect();
            assert_eq!(bits(&got), bits(&expected), "{window:?}");
        }
    }
}
