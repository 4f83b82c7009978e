"""What users iterate over: the dataset of rendered sequences (:mod:`.dataset`), the batch augmentation
(:mod:`.augment`, its worker pool :mod:`.render_pool`, its training-loop step :mod:`.augment_step`),
patch pairs cut from samples (:mod:`.pairs`) and a contact sheet of samples (:mod:`.preview`)."""
