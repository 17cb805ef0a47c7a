#!/usr/bin/python3
"""Writes assets/volumes/blob.vdb, the small OpenVDB test volume (see assets/README.md).

Made once with Debian 12's OpenVDB 10.0.1 Python binding (`apt-get install python3-openvdb`,
run with /usr/bin/python3) and committed; rerunning it reproduces the grids (the file's UUID
differs). It prints the facts the tests check, as OpenVDB itself reports them.
"""
import os
import pyopenvdb as vdb

out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "blob.vdb")

# "density": a lopsided blob on the index box [-6, 9] x [0, 11] x [-4, 5], plus one constant
# 8^3 block at [16, 23] x [0, 7] x [0, 7] that OpenVDB stores as a single active tile.
density = vdb.FloatGrid()  # background 0
density.name = "density"
acc = density.getAccessor()
for i in range(-6, 10):
    for j in range(0, 12):
        for k in range(-4, 6):
            x, y, z = (i - 1.5) / 8.0, (j - 5.5) / 6.0, (k - 0.5) / 5.0
            v = 1.0 - (x * x + y * y + z * z)
            if v > 0.0:
                acc.setValueOn((i, j, k), round(v * (1.0 + 0.05 * j), 4))
density.fill((16, 0, 0), (23, 7, 7), 0.25, True)
density.prune()
# Non-uniform voxel size with a translation: index -> world is x_w = s * x_i + t.
density.transform = vdb.createLinearTransform(
    [[0.1, 0, 0, 0], [0, 0.05, 0, 0], [0, 0, 0.08, 0], [0.2, -0.1, -0.3, 1]]
)

# "temperature": another float grid (so a file holds several names).
temperature = vdb.FloatGrid()
temperature.name = "temperature"
temperature.getAccessor().setValueOn((0, 0, 0), 300.0)
temperature.transform = density.transform

# "velocity": a vector grid (not a density; the loader must refuse it).
velocity = vdb.Vec3SGrid()
velocity.name = "velocity"
velocity.getAccessor().setValueOn((1, 2, 3), (1.0, 0.0, 0.0))

vdb.write(out, grids=[density, temperature, velocity])

print("file:", out, os.path.getsize(out), "bytes")
print("transform:", density.transform)
print("activeVoxelCount:", density.activeVoxelCount())
print("evalActiveVoxelBoundingBox:", density.evalActiveVoxelBoundingBox())
print("leafCount:", density.leafCount(), "nonLeafCount:", density.nonLeafCount())
print("evalMinMax:", density.evalMinMax())
ca = density.getConstAccessor()
for ijk in [(1, 5, 0), (2, 6, 1), (-6, 5, 0), (9, 5, 0), (1, 0, 0), (20, 3, 4), (10, 5, 0), (0, 12, 0)]:
    print("value", ijk, ca.getValue(ijk), "active" if ca.isValueOn(ijk) else "inactive")
for ijk in [(1, 5, 0), (20, 3, 4)]:
    print("world of", ijk, density.transform.indexToWorld(ijk))
for name, g in [("temperature", temperature), ("velocity", velocity)]:
    print(name, g.valueTypeName, g.activeVoxelCount())
print("metadata:", {k: v for k, v in vdb.readMetadata(out).items()})
print("grid metadata:", vdb.readGridMetadata(out, "density").metadata)
