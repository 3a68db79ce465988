-- What a running job reports beside its stage and fraction (issue 17): the bytes of the cloud
-- read and the story running, as JSON ({"read": {"bytes", "total"}, "story": {"number", "count"}}).
ALTER TABLE jobs ADD COLUMN progress_detail TEXT;
