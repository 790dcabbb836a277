"""The Geometry Nodes scatter graph (the one definition; the add-on's sync tests, its Cycles comparison and the
instancing benchmark build it): a grid's points, each given an icosphere (a material set on it), randomly rotated
and non-uniformly scaled (Random Value, seed 0); optionally a row of mirrored ones too.

    from blender_kit import scatter
    host = scatter.add(scatter.graph(size=(6, 4), points=(6, 5)), location=(0, 0, 1))
"""

from __future__ import annotations


def graph(name: str = "Scatter", *, size=(6.0, 4.0), points=(6, 5), radius: float = 0.35, subdivisions: int = 2,
          material=None, scale=((0.5, 0.5, 0.5), (1.2, 1.0, 0.8)), smooth: bool = False, mirrored_row=None):
    """A GeometryNodeTree: ``points`` (nx, ny) grid points over ``size`` (x, y), an icosphere of ``radius`` and
    ``subdivisions`` on each (shade smooth if ``smooth``, ``material`` set), rotated by a random vector in
    [0, 3]³ and scaled by one in ``scale`` (min, max). ``mirrored_row``: a dict ``count``, ``start``, ``offset``,
    ``rotation``, ``scale`` (a negative component mirrors) adds that line of instances."""
    import bpy

    ng = bpy.data.node_groups.new(name, "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = ng.nodes, ng.links
    out = nodes.new("NodeGroupOutput")
    grid = nodes.new("GeometryNodeMeshGrid")
    grid.inputs["Size X"].default_value, grid.inputs["Size Y"].default_value = size
    grid.inputs["Vertices X"].default_value, grid.inputs["Vertices Y"].default_value = points
    ico = nodes.new("GeometryNodeMeshIcoSphere")
    ico.inputs["Radius"].default_value, ico.inputs["Subdivisions"].default_value = radius, subdivisions
    mat = nodes.new("GeometryNodeSetMaterial")
    mat.inputs["Material"].default_value = material
    mesh = ico.outputs["Mesh"]
    if smooth:
        shade = nodes.new("GeometryNodeSetShadeSmooth")
        links.new(mesh, shade.inputs["Geometry"])
        mesh = shade.outputs["Geometry"]
    links.new(mesh, mat.inputs["Geometry"])
    rot = nodes.new("FunctionNodeRandomValue")
    rot.data_type = "FLOAT_VECTOR"
    rot.inputs["Max"].default_value = (3.0, 3.0, 3.0)
    rnd = nodes.new("FunctionNodeRandomValue")
    rnd.data_type = "FLOAT_VECTOR"
    rnd.inputs["Min"].default_value, rnd.inputs["Max"].default_value = scale
    iop = nodes.new("GeometryNodeInstanceOnPoints")
    links.new(grid.outputs["Mesh"], iop.inputs["Points"])
    links.new(mat.outputs["Geometry"], iop.inputs["Instance"])
    links.new(rot.outputs["Value"], iop.inputs["Rotation"])
    links.new(rnd.outputs["Value"], iop.inputs["Scale"])
    result = iop.outputs["Instances"]
    if mirrored_row is not None:
        row = nodes.new("GeometryNodeMeshLine")
        row.inputs["Count"].default_value = mirrored_row["count"]
        row.inputs["Start Location"].default_value = mirrored_row["start"]
        row.inputs["Offset"].default_value = mirrored_row["offset"]
        mirrored = nodes.new("GeometryNodeInstanceOnPoints")
        mirrored.inputs["Rotation"].default_value = mirrored_row["rotation"]
        mirrored.inputs["Scale"].default_value = mirrored_row["scale"]
        links.new(row.outputs["Mesh"], mirrored.inputs["Points"])
        links.new(mat.outputs["Geometry"], mirrored.inputs["Instance"])
        join = nodes.new("GeometryNodeJoinGeometry")
        links.new(result, join.inputs["Geometry"])
        links.new(mirrored.outputs["Instances"], join.inputs["Geometry"])
        result = join.outputs["Geometry"]
    links.new(result, out.inputs[0])
    return ng


def add(node_group, location=(0.0, 0.0, 0.0), name: str = "Host"):
    """A unit plane at ``location`` whose Geometry Nodes modifier runs ``node_group``; returns the object."""
    from . import scene

    host = scene.add_plane(location, 1.0, name=name)
    host.modifiers.new("Scatter", "NODES").node_group = node_group
    return host
