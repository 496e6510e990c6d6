//! The shared, long-lived GPU objects: each node's layouts and pipelines, which the nodes
//! define in their own files (as glyphon's `Cache`), built once for the cache's device and
//! precision by the first node that asks for them and found by their type, so that this file
//! names no node. One `Cache` serves any number of nodes and views on the same device.

use std::any::{Any, TypeId};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use crate::gpu::ShaderPrecision;

/// A node's layouts and pipelines, as the [`Cache`] holds them: built once per cache and
/// shared by its clones (cloning is cheap: handles). A node's pipeline variants built on first
/// use (the march's method and light kind, the composite's output format) live behind the
/// same handles.
pub(crate) trait CachedPipelines: Clone + Send + Sync + 'static {
    /// Compiles the node's shaders and builds what does not depend on a frame.
    fn build(device: &wgpu::Device, precision: ShaderPrecision) -> Self;
}

/// Every node's layouts and pipelines on one device, each built when a node first needs it
/// (or before the first frame by [`warm_up`](Self::warm_up)). Cloning is cheap (handles); the
/// clones share what any of them builds.
///
/// Used in the [crate-level example](crate#example).
#[derive(Clone)]
pub struct Cache {
    device: wgpu::Device,
    precision: ShaderPrecision,
    /// One cell per node type: the map's lock is held only to find a cell, so a build
    /// (seconds on a software driver) holds up only those waiting for the same type, not a
    /// thread asking for pipelines another type already has (the Bevy plugin warms the rest
    /// on a background thread while frames render).
    built: Arc<Mutex<HashMap<TypeId, Arc<Built>>>>,
}

/// A node type's pipelines once built.
type Built = OnceLock<Box<dyn Any + Send + Sync>>;

impl Cache {
    /// A cache for `device`'s nodes. It compiles nothing yet: each node's shaders and
    /// pipelines are built by the first node that needs them, or all of them, with the
    /// variants a frame can use, by [`warm_up`](Self::warm_up)
    /// ([`Settings::warm_up`](crate::Settings::warm_up) through the facade).
    ///
    /// Used in the [crate-level example](crate#example).
    pub fn new(device: &wgpu::Device) -> Self {
        Self::with_precision(device, ShaderPrecision::Native)
    }

    /// As [`new`](Self::new), with the shaders' transcendental functions evaluated as
    /// `precision` says: [`ShaderPrecision::WorstCase`] is a test mode that shows, on a driver
    /// whose maths is nearly exact, what the least precise GPU that WGSL allows does to the
    /// images.
    pub fn with_precision(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        Self {
            device: device.clone(),
            precision,
            built: Arc::default(),
        }
    }

    /// The device the cache builds for.
    pub(crate) fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The precision the shaders were compiled with.
    pub fn precision(&self) -> ShaderPrecision {
        self.precision
    }

    /// The pipelines of type `P`, built for this cache's device on first use.
    pub(crate) fn get<P: CachedPipelines>(&self) -> P {
        let cell = Arc::clone(
            self.built
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .entry(TypeId::of::<P>())
                .or_default(),
        );
        cell.get_or_init(|| Box::new(P::build(&self.device, self.precision)))
            .downcast_ref::<P>()
            .expect("each type's entry holds that type")
            .clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::HeadlessGpu;
    use std::sync::mpsc;

    /// A node type whose build reports that it started, then waits to be let go.
    #[derive(Clone)]
    struct Slow;
    /// A node type built at once.
    #[derive(Clone)]
    struct Fast;

    type Gate = (
        Mutex<Option<mpsc::Sender<()>>>,
        Mutex<Option<mpsc::Receiver<()>>>,
    );
    static GATE: OnceLock<Gate> = OnceLock::new();

    impl CachedPipelines for Slow {
        fn build(_: &wgpu::Device, _: ShaderPrecision) -> Self {
            let (started, release) = GATE.get().expect("the test set the gate");
            started.lock().unwrap().take().unwrap().send(()).unwrap();
            release.lock().unwrap().take().unwrap().recv().unwrap();
            Slow
        }
    }
    impl CachedPipelines for Fast {
        fn build(_: &wgpu::Device, _: ShaderPrecision) -> Self {
            Fast
        }
    }

    /// While one type builds (seconds on lavapipe, and the Bevy plugin warms variants on a
    /// background thread), the cache's map is free: another thread finds and builds other
    /// types, and only a thread asking for the same type waits. With the map locked for the
    /// build (as before) `try_lock` fails here and the test does too; it decides by the lock's
    /// state once the build has started, not by time.
    #[test]
    fn a_build_holds_up_only_its_own_type() {
        let gpu = match HeadlessGpu::new() {
            Ok(gpu) => gpu,
            Err(e) => panic!("GPU tests need a wgpu adapter (lavapipe works): {e}"),
        };
        let cache = Cache::new(&gpu.device);
        let (started_tx, started_rx) = mpsc::channel();
        let (release_tx, release_rx) = mpsc::channel();
        assert!(GATE
            .set((Mutex::new(Some(started_tx)), Mutex::new(Some(release_rx))))
            .is_ok());
        let builder = {
            let cache = cache.clone();
            std::thread::spawn(move || {
                cache.get::<Slow>();
            })
        };
        started_rx.recv().unwrap();
        let free = cache.built.try_lock().is_ok();
        release_tx.send(()).unwrap();
        builder.join().unwrap();
        assert!(free, "the cache's map stayed locked while a type built");
        cache.get::<Fast>();
        cache.get::<Slow>();
        assert_eq!(cache.built.lock().unwrap().len(), 2);
    }
}
