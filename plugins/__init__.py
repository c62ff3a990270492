"""mi-npr's Mitsuba plugins, one per file, installed as ``mi_npr.plugins``.

Each file defines one integrator and registers it in its last line, for the active variant.
``import mi_npr`` registers them all (and again whenever the variant changes); importing this
package alone registers nothing.
"""
