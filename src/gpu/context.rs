//! The GPU context: device, queue and the cache of compute pipelines.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use super::ShaderDef;
use crate::{Error, Result};

/// Storage buffers one pipetrack shader may bind at most.
const NEEDED_STORAGE_BUFFERS: u32 = 8;

/// The device limits pipetrack needs: wgpu's downlevel defaults (which every
/// compute-capable adapter meets) with 8 storage buffers per shader stage.
///
/// Create your device with these (or higher) limits before handing it to
/// [`GpuContext::from_device`], which checks every one of them. wgpu's
/// `Limits::default()` meets them all (a unit test checks it), so a device
/// made with it serves too; `Limits::downlevel_defaults()` has 4 storage
/// buffers and does not.
/// Larger frames may need `max_storage_buffer_binding_size` and
/// `max_buffer_size` raised further: a frame's f32 image takes `4·w·h` bytes.
#[must_use]
pub fn required_limits() -> wgpu::Limits {
    wgpu::Limits { max_storage_buffers_per_shader_stage: NEEDED_STORAGE_BUFFERS, ..wgpu::Limits::downlevel_defaults() }
}

/// The device features pipetrack needs: none beyond core WebGPU.
#[must_use]
pub fn required_features() -> wgpu::Features {
    wgpu::Features::empty()
}

/// Check `limits` and `features` (a device's) against [`required_limits`]
/// and [`required_features`]; the error names the first limit that falls short.
pub(crate) fn check_device(limits: &wgpu::Limits, features: wgpu::Features) -> Result<()> {
    let mut short = None;
    required_limits().check_limits_with_fail_fn(limits, true, |limit, needed, available| {
        short.get_or_insert(Error::Limit { limit, needed, available });
    });
    if let Some(e) = short {
        return Err(e);
    }
    let missing = required_features() - features;
    if !missing.is_empty() {
        return Err(Error::MissingFeatures(missing));
    }
    Ok(())
}

/// A wgpu device and queue with pipetrack's pipelines built on it.
///
/// Create one with [`GpuContext::new`] (pipetrack finds a Vulkan adapter) or
/// [`GpuContext::from_device`] (you hand over your own device and queue).
/// Pipelines are compiled once, on first use (a [`crate::GpuBackend`]
/// compiles the ones every frame needs when it is made), and cached for the
/// life of the context. Cloning is cheap (shared state).
#[derive(Clone)]
pub struct GpuContext {
    pub(crate) device: wgpu::Device,
    pub(crate) queue: wgpu::Queue,
    adapter_name: String,
    /// Pixels each invocation of the compaction's count and scatter passes
    /// reads ([`GpuContext::compaction_run`]).
    compaction_run: u32,
    pipelines: Arc<Mutex<HashMap<(&'static str, &'static str), wgpu::ComputePipeline>>>,
    modules: Arc<Mutex<HashMap<&'static str, wgpu::ShaderModule>>>,
}

/// The backends pipetrack asks wgpu for.
const BACKENDS: wgpu::Backends = wgpu::Backends::VULKAN;

/// The first adapter whose name contains `wanted` (ignoring case), as wgpu
/// reads `WGPU_ADAPTER_NAME`; an error naming the adapters there are when
/// none does.
async fn adapter_named(instance: &wgpu::Instance, wanted: &str) -> Result<wgpu::Adapter> {
    let wanted_lower = wanted.to_lowercase();
    let mut names = Vec::new();
    for adapter in instance.enumerate_adapters(BACKENDS).await {
        let name = adapter.get_info().name;
        if name.to_lowercase().contains(&wanted_lower) {
            return Ok(adapter);
        }
        names.push(name);
    }
    Err(Error::Gpu(format!(
        "WGPU_ADAPTER_NAME={wanted:?} names no adapter (there {}: {})",
        if names.len() == 1 { "is" } else { "are" },
        if names.is_empty() { "none".to_string() } else { names.join(", ") }
    )))
}

/// The compaction's run length for a device of type `device_type`: 32 on a
/// CPU adapter (lavapipe: a long serial loop per invocation, few
/// workgroups), 8 on a GPU (reads closer together, four times the
/// workgroups; BENCHMARKS.md, "Compaction runs by device").
#[must_use]
pub fn default_compaction_run(device_type: wgpu::DeviceType) -> u32 {
    if device_type == wgpu::DeviceType::Cpu { 32 } else { 8 }
}

impl std::fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuContext").field("adapter", &self.adapter_name).finish()
    }
}

impl GpuContext {
    /// Find a Vulkan adapter (honouring `WGPU_ADAPTER_NAME` and
    /// `WGPU_POWER_PREF` from the environment) and create a device on it.
    pub fn new() -> Result<Self> {
        pollster::block_on(Self::new_async())
    }

    async fn new_async() -> Result<Self> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        desc.backends = BACKENDS;
        let instance = wgpu::Instance::new(desc);
        let adapter = match std::env::var_os("WGPU_ADAPTER_NAME") {
            Some(wanted) => adapter_named(&instance, &wanted.to_string_lossy()).await?,
            None => {
                instance
                    .request_adapter(&wgpu::RequestAdapterOptions {
                        power_preference: wgpu::PowerPreference::from_env()
                            .unwrap_or(wgpu::PowerPreference::HighPerformance),
                        ..Default::default()
                    })
                    .await?
            }
        };
        let info = adapter.get_info();
        let mut limits = required_limits();
        let available = adapter.limits();
        limits.max_storage_buffer_binding_size = available.max_storage_buffer_binding_size;
        limits.max_buffer_size = available.max_buffer_size;
        limits.max_compute_workgroup_storage_size = available.max_compute_workgroup_storage_size.min(32 * 1024);
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("pipetrack"),
                required_features: required_features(),
                required_limits: limits,
                ..Default::default()
            })
            .await?;
        let name = format!("{} ({:?}, {})", info.name, info.backend, info.driver);
        Ok(Self::wrap(device, queue, name, default_compaction_run(info.device_type)))
    }

    /// Use the caller's own device and queue (for embedding pipetrack in a
    /// wgpu program). The device must have been created with at least
    /// [`required_limits`] and [`required_features`]; every limit is checked,
    /// and the error ([`Error::Limit`], [`Error::MissingFeatures`]) names the
    /// one that falls short.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue) -> Result<Self> {
        check_device(&device.limits(), device.features())?;
        let info = device.adapter_info();
        let name = format!("{:?} (caller's device)", info.name);
        let run = default_compaction_run(info.device_type);
        Ok(Self::wrap(device, queue, name, run))
    }

    fn wrap(device: wgpu::Device, queue: wgpu::Queue, adapter_name: String, compaction_run: u32) -> Self {
        Self { device, queue, adapter_name, compaction_run, pipelines: Arc::default(), modules: Arc::default() }
    }

    /// Pixels each invocation of the compaction's count and scatter passes
    /// reads, 1 to 32 ([`default_compaction_run`] of the device's type unless
    /// set by [`GpuContext::with_compaction_run`]). The lists are the same
    /// for every value; only the speed differs.
    #[must_use]
    pub fn compaction_run(&self) -> u32 {
        self.compaction_run
    }

    /// This context on the same device with the compaction's run length set
    /// to `run` (1 to 32), with its own pipeline cache. Compaction scratch
    /// ([`crate::early::compaction::CompactionGpu`]) is sized for the run of
    /// the context that made it and must be used with that context.
    pub fn with_compaction_run(&self, run: u32) -> Result<Self> {
        if !(1..=32).contains(&run) {
            return Err(Error::Parameter(format!("compaction run {run} is not 1 to 32")));
        }
        Ok(Self::wrap(self.device.clone(), self.queue.clone(), self.adapter_name.clone(), run))
    }

    /// The value of pipeline-overridable constant `name` on this context.
    fn override_value(&self, name: &str) -> Result<f64> {
        match name {
            "COMPACTION_RUN" => Ok(f64::from(self.compaction_run)),
            _ => Err(Error::Gpu(format!("no value for the pipeline-overridable constant `{name}`"))),
        }
    }

    /// The adapter's name, backend and driver, e.g. `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, llvmpipe)`.
    #[must_use]
    pub fn adapter_name(&self) -> &str {
        &self.adapter_name
    }

    /// The wgpu device.
    #[must_use]
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The wgpu queue.
    #[must_use]
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The compute pipeline for `entry` in `shader`, compiled on first use and
    /// cached. Its bind-group layout is built from the entry point's declared
    /// [`super::Binding`]s; an entry point `shader` does not declare is an error.
    pub(crate) fn pipeline(&self, shader: &ShaderDef, entry: &'static str) -> Result<wgpu::ComputePipeline> {
        let mut pipelines = self.pipelines.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(p) = pipelines.get(&(shader.name, entry)) {
            return Ok(p.clone());
        }
        let declared = shader
            .entry_point(entry)
            .ok_or_else(|| Error::Gpu(format!("{}: entry point `{entry}` is not declared", shader.path())))?;
        let module = {
            let mut modules = self.modules.lock().unwrap_or_else(|p| p.into_inner());
            modules
                .entry(shader.name)
                .or_insert_with(|| {
                    self.device.create_shader_module(wgpu::ShaderModuleDescriptor {
                        label: Some(shader.name),
                        source: wgpu::ShaderSource::Wgsl(shader.composed_source()),
                    })
                })
                .clone()
        };
        let label = format!("pipetrack.{}.{}", shader.name, entry);
        let entries: Vec<wgpu::BindGroupLayoutEntry> =
            declared.bindings.iter().enumerate().map(|(i, b)| b.layout_entry(i as u32)).collect();
        let bind_group_layout = self
            .device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(&label), entries: &entries });
        let layout = self.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(&label),
            bind_group_layouts: &[Some(&bind_group_layout)],
            immediate_size: 0,
        });
        let constants =
            shader.overrides.iter().map(|&name| Ok((name, self.override_value(name)?))).collect::<Result<Vec<_>>>()?;
        let pipeline = self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(&label),
            layout: Some(&layout),
            module: &module,
            entry_point: Some(entry),
            compilation_options: wgpu::PipelineCompilationOptions { constants: &constants, ..Default::default() },
            cache: None,
        });
        pipelines.insert((shader.name, entry), pipeline.clone());
        Ok(pipeline)
    }

    /// Compile the given `(shader, entry)` pipelines now rather than on first
    /// use. An entry point the shader does not declare is skipped here; the
    /// dispatch that names it reports the error.
    pub(crate) fn warm_up(&self, list: &[(ShaderDef, &'static str)]) {
        for (s, e) in list {
            let _ = self.pipeline(s, e);
        }
    }

    /// Block until all work submitted to the device so far is done, the
    /// embedding application's included (bounded by a timeout).
    pub(crate) fn wait(&self) -> Result<()> {
        self.device.poll(wgpu::PollType::Wait { submission_index: None, timeout: Some(super::POLL_TIMEOUT) })?;
        Ok(())
    }

    /// Block until the submission `index` is done (bounded by a timeout),
    /// without waiting for work submitted after it.
    pub(crate) fn wait_for(&self, index: wgpu::SubmissionIndex) -> Result<()> {
        self.device.poll(wgpu::PollType::Wait { submission_index: Some(index), timeout: Some(super::POLL_TIMEOUT) })?;
        Ok(())
    }

    /// Map `buffer` for reading (the whole of `range`) and copy its bytes out.
    ///
    /// Call it after [`GpuContext::wait_for`] on the submission that last
    /// wrote `buffer`: the mapping then completes on a non-blocking poll and
    /// nothing else is waited for. If it does not (that submission is still
    /// running, or another thread's poll is delivering the mapping), this
    /// polls again until it does, never waiting for unrelated work.
    pub(crate) fn read_buffer(&self, buffer: &wgpu::Buffer, range: std::ops::Range<u64>) -> Result<Vec<u8>> {
        self.read_mapped(buffer, range, <[u8]>::to_vec)
    }

    /// Like [`GpuContext::read_buffer`], but hands the mapped bytes to `read`
    /// instead of copying them out: one copy less for a caller that decodes
    /// them into its own values.
    pub(crate) fn read_mapped<T>(
        &self,
        buffer: &wgpu::Buffer,
        range: std::ops::Range<u64>,
        read: impl FnOnce(&[u8]) -> T,
    ) -> Result<T> {
        if range.is_empty() {
            return Ok(read(&[]));
        }
        let (tx, rx) = std::sync::mpsc::channel();
        buffer.map_async(wgpu::MapMode::Read, range.clone(), move |r| {
            let _ = tx.send(r);
        });
        self.device.poll(wgpu::PollType::Poll)?;
        let started = std::time::Instant::now();
        let mapped = loop {
            match rx.recv_timeout(std::time::Duration::from_micros(50)) {
                Ok(mapped) => break mapped,
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) if started.elapsed() < super::POLL_TIMEOUT => {
                    self.device.poll(wgpu::PollType::Poll)?;
                }
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                    return Err(Error::Gpu(format!("buffer not mapped within {:?}", super::POLL_TIMEOUT)));
                }
                Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(Error::Gpu("map callback dropped".into()));
                }
            }
        };
        mapped?;
        let value = read(&buffer.get_mapped_range(range)?);
        buffer.unmap();
        Ok(value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn required_limits_pass_their_own_check() {
        check_device(&required_limits(), required_features()).unwrap();
        check_device(&wgpu::Limits::default(), wgpu::Features::empty()).unwrap();
    }

    #[test]
    fn a_short_limit_is_named() {
        let err = check_device(&wgpu::Limits::downlevel_defaults(), wgpu::Features::empty()).unwrap_err();
        assert!(
            matches!(err, Error::Limit { limit: "max_storage_buffers_per_shader_stage", needed: 8, available: 4 }),
            "{err:?}"
        );
        assert!(err.to_string().contains("max_storage_buffers_per_shader_stage is 4, pipetrack needs 8"), "{err}");
        let err = check_device(&wgpu::Limits::downlevel_webgl2_defaults(), wgpu::Features::empty()).unwrap_err();
        assert!(matches!(err, Error::Limit { .. }), "{err:?}");
    }
}
