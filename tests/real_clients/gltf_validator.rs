//! The Khronos glTF-Validator (npm `gltf-validator`) on `scene.glb` written by wavrad.
