"""Test and benchmark helpers that ship with the package: a tiny real Qwen2.5-VL checkpoint builder.
The product never imports this package."""
