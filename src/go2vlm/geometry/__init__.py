"""Pure geometry shared by the stages: the pinhole camera model, rotations, and the image-target
convention of /detected_target. No DDS, no MuJoCo: numpy and the standard library only."""
