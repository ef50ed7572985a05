"""Other engines and formats: MJCF/URDF export and the validation against MuJoCo."""
