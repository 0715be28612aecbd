"""The live dashboard, in three parts: its feed (feed.py: what the store holds, read once per version and
shared), its page (page.py: one browser tab's Bokeh document) and its server (server.py: serves the page
from a background thread and says farewell when it stops)."""
