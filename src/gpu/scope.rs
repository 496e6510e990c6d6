//! Validation errors of the caller's resources caught where wgpu reports them, as typed errors.

use std::future::Future;
use std::pin::pin;
use std::task::{Context, Poll, Waker};

use crate::error::{Error, Result};

/// Runs `f` inside a validation error scope of `device` and turns an error wgpu reports in it
/// into [`Error::Validation`] naming `during`; `f`'s own error comes first. On native backends
/// an error scope's result is ready when it is popped; where it is not (WebGPU reports it
/// asynchronously), nothing is waited for and `f`'s result is returned.
pub(crate) fn validated<T>(
    device: &wgpu::Device,
    during: &'static str,
    f: impl FnOnce() -> Result<T>,
) -> Result<T> {
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let value = f();
    let error = ready(scope.pop()).flatten();
    let value = value?;
    match error {
        Some(e) => Err(Error::Validation {
            during,
            message: e.to_string(),
        }),
        None => Ok(value),
    }
}

/// The future's output if it is ready at its first poll.
fn ready<F: Future>(future: F) -> Option<F::Output> {
    match pin!(future).poll(&mut Context::from_waker(Waker::noop())) {
        Poll::Ready(output) => Some(output),
        Poll::Pending => None,
    }
}
