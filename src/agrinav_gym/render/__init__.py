"""The render engine: scenes, ray casting and rasterisation, shading and pixel noise.

Everything a camera needs to turn a field into pixels, and nothing about sensors, physics or
the env: the crop and robot meshes (``plant_meshes``, ``robot_mesh``), the tiled mesh scene
(``mesh_scene``) and the proxy plants (``proxy_plants`` with the fitted ``proxy_params``),
Embree (``embree``), the compiled kernels through ctypes (``native``, sources in ``csrc/``),
the rasteriser (``raster_view``), ``shading`` and ``pixel_noise``. The cameras in
``agrinav_gym.sensors`` and the chase view (``agrinav_gym.chase_view``) are built on it; it
imports only ``config``, ``interface`` and ``robot`` from the rest of the package.
"""
