"""Bags: record topics into rosbag2/MCAP bags (`go2vlm record`, `BagRecorder`) and play them back
(`go2vlm play`, `PlayerNode`)."""
