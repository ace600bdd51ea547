"""Write the meshes of the mesh_arm test robot (run once; the files are committed).

``python tests/robots/mesh_arm/make_meshes.py`` writes, with trimesh (and pycollada for DAE):

* ``meshes/link1.stl`` — binary STL, a cylinder of radius 0.04 m and length 0.3 m along z,
  centred on its frame (24 sections);
* ``meshes/link2.obj`` — OBJ, a box 0.3 x 0.05 x 0.05 m centred on its frame;
* ``meshes/link3.dae`` — COLLADA, a cone of radius 30 and height 200 in millimetres (base at
  z = 0, apex at z = 200; the URDF scales it by 0.001), 16 sections.
"""

from pathlib import Path

import trimesh

HERE = Path(__file__).resolve().parent / "meshes"


def main() -> None:
    HERE.mkdir(exist_ok=True)
    trimesh.creation.cylinder(radius=0.04, height=0.3, sections=24).export(HERE / "link1.stl")
    trimesh.creation.box(extents=[0.3, 0.05, 0.05]).export(HERE / "link2.obj")
    trimesh.creation.cone(radius=30.0, height=200.0, sections=16).export(HERE / "link3.dae")


if __name__ == "__main__":
    main()
