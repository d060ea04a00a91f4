//! Helpers shared by integration tests, one copy each (each test file that needs them says
//! `mod common;`; each uses some of them, hence `dead_code` allowed here):
//! - `service`: an in-process server on port 0, a client, submitting and polling jobs, multipart
//!   bodies, `expect_error` (the error JSON of docs/contract.md);
//! - `scenes`: the sample scenes those tests submit;
//! - `gltf`: editing GLBs, palette images, the glowing quad of the texture tests;
//! - `faces`: merging with the validator's check;
//! - `cli`: running the `wavrad` binary;
//! - `clients`: the real clients (Node.js tools, Chromium) and the skip rule when they are missing.
#![allow(dead_code)]

pub mod cli;
pub mod clients;
pub mod faces;
pub mod gltf;
pub mod scenes;
pub mod service;
