"""A real station's digital twin (docs/twin.md): the station read from its files, the
facet found in the image, its slopes reconstructed from decoded screen points, and the
glshade scene that renders what the nominal facet would give."""
