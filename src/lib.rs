//! # asbuilt (the service)
//!
//! The HTTP service around the `asbuilt-plan` pipeline: uploads stream to a [`storage::BlobStore`],
//! jobs live in a [`queue::JobStore`], background [`worker`]s run the pipeline on blocking
//! threads, and [`router`] maps the v1 API onto [`controllers`].

pub mod app;
pub mod auth;
pub mod config;
pub mod controllers;
pub mod errors;
pub mod limits;
pub mod metrics;
pub mod net;
pub mod openapi;
pub mod queue;
pub mod router;
pub mod storage;
pub mod views;
pub mod webhooks;
pub mod worker;
