"""The sensor models: the rigorous SceneModel (camera, line timing, trajectory, corrections) and the
RPC scene, with the same interface (ground_to_image, image_to_ground); intersection of rays."""
