//! The dashboard in headless Chromium (npm `playwright-core`, Debian's `chromium`).
