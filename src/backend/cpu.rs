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
use crate::early::sobel::{SobelOutput, sobel_cpu};
use crate::early::temporal_diff;
use crate::early::window_energy;
use crate::early::zero_crossing::{Edgels, zero_crossing_cpu};
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
        self.spare = features;
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
        for step in plan.steps() {
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
                Step::Sobel { input, output } => img.sobel_into(input, output),
                Step::Log(p) => log_cpu(&img.luma, &p, &mut self.tmp, &mut self.tmp2, &mut img.log)?,
                Step::ZeroCrossings(p) => zero_crossing_cpu(&img.log, &p, &mut img.edgels),
                Step::Compact { list, select, theta, magnitude, params } => {
                    let mut features = recycled_list(self.spare.list_mut(list));
                    compaction_cpu(
                        img.source(select),
                        img.source(theta),
                        img.source(magnitude),
                        &params,
                        &mut features,
                    )?;
                    *out.list_mut(list) = Some(features);
                }
                Step::EmptyList(list) => *out.list_mut(list) = Some(recycled_list(self.spare.list_mut(list))),
                Step::Pyramids { gradient, returned } => {
                    // Computed straight into the levels handed out (recycled
                    // ones when the caller gave them back): no copy of every level.
                    let (mut cpf_levels, mut edge_levels) = self.spare.pyramids.take().unwrap_or_default();
                    cpf::cpf_cpu(&img.luma, &mut cpf_levels);
                    let g = img.sobel(gradient);
                    edge_pyramid::edge_pyramid_cpu(&g.gx, &g.gy, &mut edge_levels)?;
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
