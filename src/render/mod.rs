//! The wgpu cloud renderer (DESIGN §2–4).
