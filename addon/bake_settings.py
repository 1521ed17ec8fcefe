"""The thickness-bake settings of the SSS Lab panel (``scene.sss_lab.bake``)."""

from __future__ import annotations

import bpy

from ..core.scene.thickness import BakeSettings, default_source

_DEFAULTS = BakeSettings()


class SSSLabBakeSettings(bpy.types.PropertyGroup):
    target: bpy.props.EnumProperty(
        name="Target",
        description="Where the thickness map goes",
        items=[
            ("attribute", "Color Attribute", "A float color attribute on the mesh (no UV map needed)"),
            ("image", "Image Texture", "An image over the active UV map, saved to the image folder"),
        ],
        default=_DEFAULTS.target,
    )
    convention: bpy.props.EnumProperty(
        name="Convention",
        description="What the values mean (stored with the map)",
        items=[
            ("translucency", "Translucency (1 = thin)", "1 - inside AO: thin parts bright, as STA expects"),
            ("thickness", "Thickness (1 = thick)", "Inside AO: thick parts bright, as some engines expect"),
        ],
        default=_DEFAULTS.convention,
    )
    source: bpy.props.EnumProperty(
        name="Source",
        description="What the map is measured from",
        items=[
            ("ao", "Ambient Occlusion", "Cycles' inside ambient occlusion: STA's local thickness"),
            (
                "ray",
                "Ray Thickness",
                "The distance to the far side along the inward normals, as a slab of that thickness bakes "
                "(vertices only; better for tubes and balls)",
            ),
        ],
        default=_DEFAULTS.source,
    )
    samples: bpy.props.IntProperty(
        name="Samples",
        description="Ambient occlusion rays per vertex or texel",
        default=_DEFAULTS.samples,
        min=1,
        max=4096,
        soft_max=512,
    )
    distance: bpy.props.FloatProperty(
        name="Distance",
        description="Longest ray: parts thicker than this count as fully thick. "
        "0 = automatic (a quarter of the diagonal of each object's bounding box)",
        default=_DEFAULTS.distance_su,
        min=0.0,
        soft_max=10.0,
        subtype="DISTANCE",
        unit="LENGTH",
    )
    only_local: bpy.props.BoolProperty(
        name="Only Local",
        description="Only the object itself counts (else every rendered object occludes)",
        default=_DEFAULTS.only_local,
    )
    attribute_name: bpy.props.StringProperty(
        name="Attribute", description="Name of the color attribute", default=_DEFAULTS.attribute_name
    )
    resolution: bpy.props.IntProperty(
        name="Resolution",
        description="Width and height of the image in pixels",
        default=_DEFAULTS.resolution_px,
        min=1,
        max=16384,
        soft_max=8192,
        subtype="PIXEL",
    )
    margin: bpy.props.IntProperty(
        name="Margin",
        description="Pixels the map is extended past the UV islands",
        default=_DEFAULTS.margin_px,
        min=0,
        max=64,
        subtype="PIXEL",
    )
    image_format: bpy.props.EnumProperty(
        name="Format",
        items=[
            ("OPEN_EXR", "OpenEXR (32-bit float)", "Float32 OpenEXR"),
            ("PNG", "PNG (16-bit)", "16 bits per channel PNG, linear"),
        ],
        default=_DEFAULTS.image_format,
    )
    image_folder: bpy.props.StringProperty(
        name="Folder",
        description="Folder the images are saved in (// = beside the .blend file)",
        default=_DEFAULTS.image_folder,
        subtype="DIR_PATH",
    )
    link_materials: bpy.props.BoolProperty(
        name="Add to Materials",
        description="Add the map to the object's materials, feeding a Shader AOV output",
        default=_DEFAULTS.link_materials,
    )
    aov_name: bpy.props.StringProperty(
        name="AOV", description="Name of the Shader AOV the map feeds", default=_DEFAULTS.aov_name
    )

    def to_settings(self) -> BakeSettings:
        return BakeSettings(
            target=self.target,
            convention=self.convention,
            # The ray source measures at the vertices: an image takes its target's default source.
            source=self.source if self.target == "attribute" else default_source(self.target),
            samples=self.samples,
            distance_su=float(self.distance),
            only_local=self.only_local,
            attribute_name=self.attribute_name,
            resolution_px=self.resolution,
            margin_px=self.margin,
            image_format=self.image_format,
            image_folder=self.image_folder,
            link_materials=self.link_materials,
            aov_name=self.aov_name,
        )


classes = (SSSLabBakeSettings,)
