"""MJCF files below the recorder and the contact designer: their files, loading, `<pair>`s.

Owns: the files a model is made of (`files`: includes, attached models, assets, their
encoding), parsing and compiling a model with MuJoCo's warnings kept (`load`), and a model's
text with `<pair>` elements written in, every other byte kept (`pairs`).

May import: MuJoCo, `impactlab.errors`. Must not import: any stage, `contact`, `logs`.
"""
