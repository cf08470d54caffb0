"""The 3D PyBullet backend: the torque-controlled Panda, its scene, dynamics and friction."""
