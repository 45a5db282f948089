"""The data: trajectories and their files (``.npz``, ``.csv``), ROS bags, atomic writes."""
