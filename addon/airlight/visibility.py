"""Which objects show up in the render of a view layer (shared by every exporter)."""

import bpy


def render_hidden_collections(view_layer):
    """Names of collections whose objects do not render in `view_layer`."""
    hidden = set()

    def walk(layer_collection, parent_hidden):
        collection = layer_collection.collection
        is_hidden = parent_hidden or layer_collection.exclude or collection.hide_render
        if is_hidden:
            hidden.add(collection.name)
        for child in layer_collection.children:
            walk(child, is_hidden)

    if view_layer is not None:
        for child in view_layer.layer_collection.children:
            walk(child, False)
    return hidden


class RenderVisibility:
    """`visible(obj)`: whether an original (not instanced) object shows up in the render of
    `view_layer`: it renders itself (hide_render off) and at least one collection holding it
    renders there (a collection outside the view layer's tree, or a scene's master
    collection, counts as rendering; an object in no collection renders).

    The collections' members are listed once, on the first question: asking each object
    for its users_collection scans every collection of the file, ~0.1 ms per object (a
    3000-object scene spent ~0.35 s per pass over its instances)."""

    def __init__(self, view_layer):
        self._view_layer = view_layer
        self._shown = self._linked = None

    def _list_members(self):
        hidden = render_hidden_collections(self._view_layer)
        self._shown, self._linked = set(), set()
        members = [(c.name not in hidden, c.objects) for c in bpy.data.collections]
        members += [(True, scene.collection.objects) for scene in bpy.data.scenes]
        for shown, objects in members:
            pointers = {obj.as_pointer() for obj in objects}
            self._linked |= pointers
            if shown:
                self._shown |= pointers

    def __call__(self, obj):
        original = obj.original
        if original.hide_render:
            return False
        if self._shown is None:
            self._list_members()
        pointer = original.as_pointer()
        return pointer in self._shown or pointer not in self._linked
