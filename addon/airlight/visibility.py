"""Which objects show up in the render of a view layer (shared by every exporter)."""


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


def is_render_visible(obj, hidden_collections):
    """Whether an original (not instanced) object shows up in the render."""
    original = obj.original
    if original.hide_render:
        return False
    collections = original.users_collection
    if not collections:
        return True
    # Visible when at least one collection holding it renders (the scene master
    # collection never appears in hidden_collections).
    return any(c.name not in hidden_collections for c in collections)
