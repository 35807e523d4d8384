"""A material's warning names the objects that use it (s24 new user: 'material Skin:
Subsurface Weight ... ignored' left the user hunting for the object)."""
from engine.api import box_mesh
from engine.scene import Material, Mesh, Scene


def _scene(users):
    s = Scene()
    s.add_material(Material("Hot", (3.0, 1.5, 0.5)))      # warns: base colour above 1
    s.add_material(Material("Plain", (0.5, 0.5, 0.5)))
    v, f = box_mesh((0, 0, 1), 1.0)
    for name in users:
        s.add_mesh(Mesh(name=name, vertices=v, faces=f, materials=["Plain", "Hot"]))
    s.add_mesh(Mesh(name="Other", vertices=v, faces=f, materials=["Plain"]))
    return s


def test_material_warning_lists_its_objects():
    (w,) = [w for w in _scene(["Suzanne", "Cube"]).all_warnings() if "'Hot'" in w]
    assert w.startswith("material 'Hot': base colour")
    assert w.endswith(" (used by 'Suzanne', 'Cube')")
    assert "Other" not in w


def test_many_users_are_counted_not_listed():
    names = [f"Post{i}" for i in range(7)]
    (w,) = [w for w in _scene(names).all_warnings() if "'Hot'" in w]
    assert w.endswith(" (used by 'Post0', 'Post1', 'Post2' and 4 more)")


def test_unused_material_warning_unchanged():
    s = _scene([])
    (w,) = [w for w in s.all_warnings() if "'Hot'" in w]
    assert w == s.materials["Hot"].warnings[0]
    assert len(s.all_warnings()) == len(set(s.all_warnings()))
