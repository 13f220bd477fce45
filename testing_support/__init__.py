"""Dev-only helpers for the tests, the benchmarks and scripts/ (not installed with go2vlm; no product
module imports them): tiny real Qwen2.5-VL checkpoints and their training (tiny_qwen, tiny_grounder,
train_grounder, sim_dataset), `transformers serve` of a checkpoint (serve), and synthetic frames and
views (image_frames, world_views). The tests' conftest and each benchmark put the repository root on
the path; see docs/architecture.md."""
