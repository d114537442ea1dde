use ecr_macros::ecr_method;

ecr_method!(r = 3, r = 4);

fn main() {}
