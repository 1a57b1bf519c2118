"""Seeing a run: offscreen frames of a simulation (`frames`), its sand drawn as it is
(`stage`), an MP4 of a headless run (`recorder`, its frames painted in a process of their
own: `painting` on a `drawn_model`; `encoder`), and MuJoCo's interactive viewer on a
desktop (`viewer`). (The same video made again from a run's bag is `ros.bag_video`'s,
beside the bag reader: this package reads no bag.)

The renderer reads the simulation; it never steps it nor changes its model: it draws a copy
of the model (`stage.Stage`) posed from the simulation's state."""

#: The video of a run (`rft-sim run --video`, `rft-sim render`), in its output folder.
VIDEO_FILE = 'video.mp4'
