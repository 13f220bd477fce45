"""The apps: the demos that run a whole node graph and measure it. They use the stages; no stage uses them."""
